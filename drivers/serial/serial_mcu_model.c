/* The MCU at the far end of a descriptor (the fake transport's peer end, or a pty master): the
 * real firmware core (firmware/core) on the native board (firmware/boards/native), not a model
 * of it, so the serial driver and facescand are tested against the logic that ships (issue 12:
 * one MCU model). A thread feeds the core the bytes the host sends, as the UART interrupt
 * would, and sends what the core writes. The board's virtual 1 MHz clock follows the host's
 * monotonic clock, except that a running sequence jumps straight to each step and a press holds
 * the button in virtual time: tests do not wait for either in real time.
 *
 * The native board is one set of globals (one MCU per process), so only one model runs at a
 * time: a second start fails with -EBUSY. */
#define _GNU_SOURCE
#include "facescan/serial_fake.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "boards/native/native.h"
#include "core/fw.h"

/* How long a press holds the button, and how long it stays released after: both well past
 * FW_DEBOUNCE_MS, so the core's debouncer counts exactly one press. */
#define PRESS_HOLD_MS (3u * FW_DEBOUNCE_MS)
/* Bytes handed to the core between two passes of its task: well under its FW_RX_RING. */
#define INJECT_CHUNK 64u

struct fscan_mcu_model {
	int fd;
	int wake[2];
	pthread_t thread;
	pthread_mutex_t lock;
	/* Shared with the API (under lock). */
	bool mute;
	bool hangup_armed; /* hang up once the next sequence has started */
	int hung_up;       /* 1 once it did (int: read through get_shared) */
	int scans;
	/* Thread-only state. */
	uint64_t start_us; /* host clock at start */
	uint64_t skew_us;  /* virtual time skipped ahead of the host clock */
};

static pthread_mutex_t board_lock = PTHREAD_MUTEX_INITIALIZER;
static bool board_in_use;

static uint64_t mono_us(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

/* The scan count the STATUS reply would give. */
static void note_scans(struct fscan_mcu_model *m)
{
	struct fs_status s;
	fw_core_status(&s);
	pthread_mutex_lock(&m->lock);
	m->scans = s.scans;
	pthread_mutex_unlock(&m->lock);
}

/* The board's UART transmit line. The count is taken before the bytes leave, so that a test
 * that has read a report also sees its scan counted. */
static void to_host(const uint8_t *buf, size_t len, void *ctx)
{
	struct fscan_mcu_model *m = ctx;
	note_scans(m);
	size_t done = 0;
	while (done < len) {
		/* send() where it can: a host that closed its end must not raise SIGPIPE here. */
		ssize_t w = send(m->fd, buf + done, len - done, MSG_NOSIGNAL);
		if (w < 0 && errno == ENOTSOCK)
			w = write(m->fd, buf + done, len - done);
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

/* Skips virtual time forward (the host clock does not see it). */
static void skip(struct fscan_mcu_model *m, uint64_t us)
{
	native_advance(us);
	m->skew_us += us;
}

/* One pass of the task; then, if a hangup is armed and the firmware has started a sequence
 * (lights on), the cable goes: the descriptor is shut down both ways and true says stop
 * serving. */
static bool poll_core(struct fscan_mcu_model *m)
{
	fw_core_poll();
	pthread_mutex_lock(&m->lock);
	bool armed = m->hangup_armed;
	pthread_mutex_unlock(&m->lock);
	if (!armed)
		return false;
	struct fs_status s;
	fw_core_status(&s);
	if (s.state != FS_STATE_BUSY)
		return false;
	/* Noted before the host can see the hangup, so that its reopen finds the cable pulled. */
	pthread_mutex_lock(&m->lock);
	m->hangup_armed = false;
	m->hung_up = 1;
	pthread_mutex_unlock(&m->lock);
	shutdown(m->fd, SHUT_RDWR);
	return true;
}

/* Brings the virtual clock up to the host's, runs the task, and plays a running sequence to
 * its end at once: each step lands on its own virtual tick, with a pass of the task between.
 * True: the model hung up (poll_core). */
static bool pump(struct fscan_mcu_model *m)
{
	uint64_t target = mono_us() - m->start_us + m->skew_us;
	if (target > native_now())
		native_advance(target - native_now());
	if (poll_core(m))
		return true;
	for (uint64_t due = native_next_due(); due != UINT64_MAX; due = native_next_due()) {
		skip(m, due);
		if (poll_core(m))
			return true;
	}
	return false;
}

/* Holds the button pressed (or released) for `ms` of virtual time, a task pass per ms.
 * True: the model hung up (poll_core). */
static bool hold_button(struct fscan_mcu_model *m, bool pressed, unsigned ms)
{
	native_set_button(pressed);
	for (unsigned i = 0; i < ms; i++) {
		skip(m, 1000u);
		if (poll_core(m))
			return true;
	}
	return false;
}

static void *serve(void *arg)
{
	struct fscan_mcu_model *m = arg;
	for (;;) {
		struct pollfd p[2] = {{.fd = m->wake[0], .events = POLLIN}, {.fd = m->fd, .events = POLLIN}};
		if (poll(p, 2, 10) < 0) {
			if (errno == EINTR)
				continue;
			return NULL;
		}
		if (p[0].revents & POLLIN) {
			char c;
			if (read(m->wake[0], &c, 1) == 1) {
				if (c == 'q')
					return NULL;
				if (c == 'p' && (hold_button(m, true, PRESS_HOLD_MS) ||
						 hold_button(m, false, PRESS_HOLD_MS)))
					return NULL;
			}
		}
		if (p[1].revents & POLLNVAL)
			return NULL;
		if (p[1].revents & (POLLIN | POLLHUP | POLLERR)) {
			uint8_t buf[256];
			ssize_t n = read(m->fd, buf, sizeof(buf));
			if (n == 0)
				return NULL; /* the other end is gone for good (socket pair) */
			if (n < 0) {
				/* A pty master with no slave open yet (or any more) reports EIO/POLLHUP
				 * until the host (re)opens the slave: wait for it. */
				if (errno != EIO && errno != EAGAIN && errno != EINTR)
					return NULL;
				struct timespec ts = {0, 10 * 1000000L};
				nanosleep(&ts, NULL);
			}
			pthread_mutex_lock(&m->lock);
			bool mute = m->mute;
			pthread_mutex_unlock(&m->lock);
			for (ssize_t i = 0; !mute && i < n; i += INJECT_CHUNK) {
				size_t len = (size_t)(n - i) < INJECT_CHUNK ? (size_t)(n - i) : INJECT_CHUNK;
				native_uart_inject(buf + i, len);
				if (pump(m))
					return NULL;
			}
		}
		if (pump(m))
			return NULL;
	}
}

int fscan_mcu_model_start(int fd, struct fscan_mcu_model **ret_model)
{
	if (fd < 0 || !ret_model)
		return -EINVAL;
	pthread_mutex_lock(&board_lock);
	bool busy = board_in_use;
	board_in_use = true;
	pthread_mutex_unlock(&board_lock);
	if (busy)
		return -EBUSY;
	int r = -ENOMEM;
	struct fscan_mcu_model *m = calloc(1, sizeof(*m));
	if (!m)
		goto err_board;
	if (pipe2(m->wake, O_CLOEXEC) < 0) {
		r = -errno;
		goto err_free;
	}
	m->fd = fd;
	m->start_us = mono_us() - native_now(); /* the board's clock never runs backwards */
	pthread_mutex_init(&m->lock, NULL);
	/* Power-on: the core sends EVT_BOOT. FS_CMD_DEBUG_BUTTON may press the button, as on
	 * the other simulated boards. */
	native_set_uart_sink(to_host, m);
	native_set_debug_inputs(true);
	native_set_button(false);
	native_reset(FS_RESET_POWER);
	fw_core_init();
	r = -pthread_create(&m->thread, NULL, serve, m);
	if (r < 0)
		goto err_sink;
	*ret_model = m;
	return 0;
err_sink:
	native_set_uart_sink(NULL, NULL);
	pthread_mutex_destroy(&m->lock);
	close(m->wake[0]);
	close(m->wake[1]);
err_free:
	free(m);
err_board:
	pthread_mutex_lock(&board_lock);
	board_in_use = false;
	pthread_mutex_unlock(&board_lock);
	return r;
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
	native_set_uart_sink(NULL, NULL);
	pthread_mutex_destroy(&model->lock);
	close(model->wake[0]);
	close(model->wake[1]);
	free(model);
	pthread_mutex_lock(&board_lock);
	board_in_use = false;
	pthread_mutex_unlock(&board_lock);
}

int fscan_mcu_model_press(struct fscan_mcu_model *model)
{
	return poke(model, 'p');
}

/* The API's view of the state shared with the thread: each read or write under the lock. */
static int set_shared(struct fscan_mcu_model *m, bool *field, bool value)
{
	pthread_mutex_lock(&m->lock);
	*field = value;
	pthread_mutex_unlock(&m->lock);
	return 0;
}

static int get_shared(struct fscan_mcu_model *m, const int *field)
{
	pthread_mutex_lock(&m->lock);
	int r = *field;
	pthread_mutex_unlock(&m->lock);
	return r;
}

int fscan_mcu_model_set_mute(struct fscan_mcu_model *model, bool mute)
{
	return model ? set_shared(model, &model->mute, mute) : -EINVAL;
}

int fscan_mcu_model_hangup_on_sequence(struct fscan_mcu_model *model)
{
	if (!model)
		return -EINVAL;
	int type;
	socklen_t len = sizeof(type);
	if (getsockopt(model->fd, SOL_SOCKET, SO_TYPE, &type, &len) < 0)
		return -errno;
	return set_shared(model, &model->hangup_armed, true);
}

int fscan_mcu_model_hung_up(struct fscan_mcu_model *model)
{
	return model ? get_shared(model, &model->hung_up) : -EINVAL;
}

int fscan_mcu_model_scans(struct fscan_mcu_model *model)
{
	return model ? get_shared(model, &model->scans) : -EINVAL;
}
