/* An in-process model of the trigger MCU: speaks the firmware protocol on a descriptor (the
 * fake transport's peer end, or a pty master), so that the serial driver and facescand can be
 * tested without the firmware. It follows firmware/protocol/protocol.h: responses echo the
 * command's seq, events carry the model's own counter, decode errors are NACKed with seq 0. */
#define _GNU_SOURCE
#include "facescan/serial_fake.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

struct fscan_mcu_model {
	int fd;
	int wake[2];
	pthread_t thread;
	pthread_mutex_t lock;
	/* Shared with the API (under lock). */
	bool mute;
	int commands, scans_fired;
	uint8_t pending_fault;
	/* Thread-only state. */
	struct fs_decoder dec;
	uint8_t state, fault;
	struct fs_timing timing;
	uint16_t scans, buttons, rx_errors;
	uint8_t event_seq;
	struct timespec boot;
};

static void send_frame(struct fscan_mcu_model *m, const struct fs_frame *f)
{
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t len;
	if (fs_frame_encode(f, buf, sizeof(buf), &len) < 0)
		return;
	size_t done = 0;
	while (done < len) {
		ssize_t w = write(m->fd, buf + done, len - done);
		if (w < 0) {
			if (errno == EAGAIN || errno == EINTR) {
				struct pollfd p = {.fd = m->fd, .events = POLLOUT};
				poll(&p, 1, 100);
				continue;
			}
			return; /* hung up: nobody to tell */
		}
		done += (size_t)w;
	}
}

static void send_event(struct fscan_mcu_model *m, struct fs_frame *f)
{
	f->seq = ++m->event_seq;
	send_frame(m, f);
}

static void respond_ack(struct fscan_mcu_model *m, const struct fs_frame *cmd)
{
	struct fs_frame r;
	fs_frame_init(&r, FS_RSP_ACK, cmd->seq);
	fs_ack_put(&r, cmd->type);
	send_frame(m, &r);
}

static void respond_nack(struct fscan_mcu_model *m, uint8_t seq, uint8_t cmd, uint8_t err)
{
	struct fs_frame r;
	fs_frame_init(&r, FS_RSP_NACK, seq);
	struct fs_nack n = {.err = err, .cmd = cmd};
	fs_nack_put(&r, &n);
	send_frame(m, &r);
}

/* One complete sequence at the configured timing (1 tick = 1 us), reported as done. */
static void run_scan(struct fscan_mcu_model *m, uint8_t trigger)
{
	const struct fs_timing *t = &m->timing;
	uint32_t step_us[FS_STEP__COUNT] = {0, t->proj_settle_us, t->exposure_us, t->proj_hold_us,
					   t->flash_delay_us, t->flash_settle_us, t->flash_exposure_us,
					   t->flash_hold_us};
	static const uint8_t lines[FS_STEP__COUNT] = {
		FS_LINES_PROJ, FS_LINES_PROJ | FS_LINES_SHUT, FS_LINES_PROJ, 0,
		FS_LINE_FLASH, FS_LINE_FLASH | FS_LINES_SHUT, FS_LINE_FLASH, 0,
	};
	struct fs_report rep = {.result = FS_REPORT_DONE, .trigger = trigger, .steps = FS_STEP__COUNT, .lines_end = 0};
	uint32_t tick = 0;
	for (int i = 0; i < FS_STEP__COUNT; i++) {
		tick += step_us[i];
		rep.tick[i] = tick;
		rep.lines[i] = lines[i];
	}
	rep.scan = ++m->scans;
	m->state = FS_STATE_IDLE;
	pthread_mutex_lock(&m->lock);
	m->scans_fired++;
	pthread_mutex_unlock(&m->lock);
	struct fs_frame f;
	fs_frame_init(&f, FS_EVT_REPORT, 0);
	fs_report_put(&f, &rep);
	send_event(m, &f);
}

static void press(struct fscan_mcu_model *m)
{
	struct fs_button b = {.started = m->state == FS_STATE_ARMED, .count = ++m->buttons};
	struct fs_frame f;
	fs_frame_init(&f, FS_EVT_BUTTON, 0);
	fs_button_put(&f, &b);
	send_event(m, &f);
	if (b.started)
		run_scan(m, FS_TRIGGER_BUTTON);
}

static uint32_t uptime_ms(const struct fscan_mcu_model *m)
{
	struct timespec now;
	clock_gettime(CLOCK_MONOTONIC, &now);
	return (uint32_t)((now.tv_sec - m->boot.tv_sec) * 1000 + (now.tv_nsec - m->boot.tv_nsec) / 1000000);
}

static void handle(struct fscan_mcu_model *m, const struct fs_frame *cmd)
{
	if (!fs_type_is_command(cmd->type)) {
		respond_nack(m, cmd->seq, cmd->type, FS_ERR_UNKNOWN_CMD);
		return;
	}
	if (cmd->version != FS_PROTO_VERSION && cmd->type != FS_CMD_HELLO) {
		respond_nack(m, cmd->seq, cmd->type, FS_ERR_VERSION);
		return;
	}
	bool no_body = cmd->type != FS_CMD_SET_TIMING && cmd->type != FS_CMD_DEBUG_BUTTON;
	if (no_body && cmd->len != 0) {
		respond_nack(m, cmd->seq, cmd->type, FS_ERR_LENGTH);
		return;
	}
	struct fs_frame r;
	switch (cmd->type) {
	case FS_CMD_HELLO: {
		struct fs_hello h = {.proto_version = FS_PROTO_VERSION, .fw_major = 0, .fw_minor = 1,
				     .board = FS_BOARD_NATIVE, .tick_hz = 1000000u, .max_body = FS_PROTO_MAX_BODY};
		fs_frame_init(&r, FS_RSP_HELLO, cmd->seq);
		fs_hello_put(&r, &h);
		send_frame(m, &r);
		return;
	}
	case FS_CMD_GET_TIMING:
		fs_frame_init(&r, FS_RSP_TIMING, cmd->seq);
		fs_timing_put(&r, &m->timing);
		send_frame(m, &r);
		return;
	case FS_CMD_SET_TIMING: {
		struct fs_timing t;
		if (fs_timing_get(cmd, &t) < 0) {
			respond_nack(m, cmd->seq, cmd->type, FS_ERR_LENGTH);
		} else if (fs_timing_validate(&t) < 0) {
			respond_nack(m, cmd->seq, cmd->type, FS_ERR_RANGE);
		} else {
			m->timing = t;
			respond_ack(m, cmd);
		}
		return;
	}
	case FS_CMD_STATUS: {
		struct fs_status s = {.state = m->state, .fault = m->fault, .reset_cause = FS_RESET_POWER,
				      .lines = 0, .scans = m->scans, .rx_errors = m->rx_errors,
				      .buttons = m->buttons, .uptime_ms = uptime_ms(m)};
		fs_frame_init(&r, FS_RSP_STATUS, cmd->seq);
		fs_status_put(&r, &s);
		send_frame(m, &r);
		return;
	}
	case FS_CMD_CLEAR_FAULT:
		m->state = FS_STATE_IDLE;
		m->fault = FS_FAULT_NONE;
		respond_ack(m, cmd);
		return;
	case FS_CMD_DEBUG_BUTTON: {
		uint16_t hold;
		if (fs_debug_button_get(cmd, &hold) < 0) {
			respond_nack(m, cmd->seq, cmd->type, FS_ERR_LENGTH);
			return;
		}
		respond_ack(m, cmd);
		press(m);
		return;
	}
	case FS_CMD_ARM:
	case FS_CMD_DISARM:
	case FS_CMD_FIRE:
	case FS_CMD_ABORT:
		break;
	default:
		respond_nack(m, cmd->seq, cmd->type, FS_ERR_UNKNOWN_CMD);
		return;
	}
	if (m->state == FS_STATE_FAULT && cmd->type != FS_CMD_ABORT && cmd->type != FS_CMD_DISARM) {
		respond_nack(m, cmd->seq, cmd->type, FS_ERR_FAULT);
		return;
	}
	respond_ack(m, cmd);
	if (cmd->type == FS_CMD_ARM)
		m->state = FS_STATE_ARMED;
	else if (cmd->type == FS_CMD_DISARM)
		m->state = m->state == FS_STATE_FAULT ? FS_STATE_FAULT : FS_STATE_IDLE;
	else if (cmd->type == FS_CMD_FIRE)
		run_scan(m, FS_TRIGGER_HOST);
	/* ABORT: sequences finish within run_scan, so there is never one to abort here. */
}

static void *serve(void *arg)
{
	struct fscan_mcu_model *m = arg;
	struct fs_frame boot;
	fs_frame_init(&boot, FS_EVT_BOOT, 0);
	struct fs_boot b = {.reset_cause = FS_RESET_POWER, .proto_version = FS_PROTO_VERSION};
	fs_boot_put(&boot, &b);
	send_event(m, &boot);
	for (;;) {
		struct pollfd p[2] = {{.fd = m->wake[0], .events = POLLIN}, {.fd = m->fd, .events = POLLIN}};
		if (poll(p, 2, -1) < 0) {
			if (errno == EINTR)
				continue;
			return NULL;
		}
		if (p[0].revents & POLLIN) {
			char c;
			if (read(m->wake[0], &c, 1) == 1) {
				if (c == 'q')
					return NULL;
				if (c == 'p')
					press(m);
				if (c == 'f') {
					pthread_mutex_lock(&m->lock);
					m->fault = m->pending_fault;
					pthread_mutex_unlock(&m->lock);
					m->state = FS_STATE_FAULT;
					struct fs_frame f;
					fs_frame_init(&f, FS_EVT_FAULT, 0);
					struct fs_fault x = {.code = m->fault, .lines = 0};
					fs_fault_put(&f, &x);
					send_event(m, &f);
				}
			}
		}
		if (p[1].revents & POLLNVAL)
			return NULL;
		if (!(p[1].revents & (POLLIN | POLLHUP | POLLERR)))
			continue;
		uint8_t buf[256];
		ssize_t n = read(m->fd, buf, sizeof(buf));
		if (n == 0)
			return NULL; /* the other end is gone for good (socket pair) */
		if (n < 0) {
			/* A pty master with no slave open yet (or any more) reports EIO/POLLHUP
			 * until the host (re)opens the slave: wait for it. */
			if (errno == EIO || errno == EAGAIN || errno == EINTR) {
				struct timespec ts = {0, 10 * 1000000L};
				nanosleep(&ts, NULL);
				continue;
			}
			return NULL;
		}
		pthread_mutex_lock(&m->lock);
		bool mute = m->mute;
		pthread_mutex_unlock(&m->lock);
		for (ssize_t i = 0; i < n; i++) {
			struct fs_frame f;
			int d = fs_decoder_feed(&m->dec, buf[i], &f);
			if (d < 0) {
				m->rx_errors++;
				if (!mute)
					respond_nack(m, 0, 0, fs_err_from_decode(d));
			} else if (d == 1) {
				pthread_mutex_lock(&m->lock);
				m->commands++;
				pthread_mutex_unlock(&m->lock);
				if (!mute)
					handle(m, &f);
			}
		}
	}
}

int fscan_mcu_model_start(int fd, struct fscan_mcu_model **ret_model)
{
	if (fd < 0 || !ret_model)
		return -EINVAL;
	struct fscan_mcu_model *m = calloc(1, sizeof(*m));
	if (!m)
		return -ENOMEM;
	if (pipe2(m->wake, O_CLOEXEC) < 0) {
		int r = -errno;
		free(m);
		return r;
	}
	m->fd = fd;
	fs_decoder_init(&m->dec);
	fs_timing_default(&m->timing);
	clock_gettime(CLOCK_MONOTONIC, &m->boot);
	pthread_mutex_init(&m->lock, NULL);
	int r = pthread_create(&m->thread, NULL, serve, m);
	if (r) {
		pthread_mutex_destroy(&m->lock);
		close(m->wake[0]);
		close(m->wake[1]);
		free(m);
		return -r;
	}
	*ret_model = m;
	return 0;
}

static int poke(struct fscan_mcu_model *m, char c)
{
	if (!m)
		return -EINVAL;
	return write(m->wake[1], &c, 1) == 1 ? 0 : -errno;
}

void fscan_mcu_model_stop(struct fscan_mcu_model *model)
{
	if (!model)
		return;
	poke(model, 'q');
	pthread_join(model->thread, NULL);
	pthread_mutex_destroy(&model->lock);
	close(model->wake[0]);
	close(model->wake[1]);
	free(model);
}

int fscan_mcu_model_press(struct fscan_mcu_model *model)
{
	return poke(model, 'p');
}

int fscan_mcu_model_fault(struct fscan_mcu_model *model, uint8_t code)
{
	if (!model || code == FS_FAULT_NONE)
		return -EINVAL;
	pthread_mutex_lock(&model->lock);
	model->pending_fault = code;
	pthread_mutex_unlock(&model->lock);
	return poke(model, 'f');
}

int fscan_mcu_model_set_mute(struct fscan_mcu_model *model, bool mute)
{
	if (!model)
		return -EINVAL;
	pthread_mutex_lock(&model->lock);
	model->mute = mute;
	pthread_mutex_unlock(&model->lock);
	return 0;
}

int fscan_mcu_model_commands(struct fscan_mcu_model *model)
{
	if (!model)
		return -EINVAL;
	pthread_mutex_lock(&model->lock);
	int n = model->commands;
	pthread_mutex_unlock(&model->lock);
	return n;
}

int fscan_mcu_model_scans(struct fscan_mcu_model *model)
{
	if (!model)
		return -EINVAL;
	pthread_mutex_lock(&model->lock);
	int n = model->scans_fired;
	pthread_mutex_unlock(&model->lock);
	return n;
}
