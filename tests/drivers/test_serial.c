/* Serial driver: one contract run twice — on the fake transport (socket pair) and on the real
 * termios backend over a real pty (openpty) — both with the in-process MCU model at the far
 * end. Then the fake device with the MCU attached (facescand's serial_device = fake) and its
 * name-keyed back doors, and framing faults, which the fake's raw peer lets us inject byte by
 * byte. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <pty.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "facescan/serial.h"
#include "serial_helpers.h"
#include "facescan/serial_fake.h"

#define T 2000 /* ms: generous, the model answers in microseconds */

/* A test bench: the link, the model, and how to pull and replug the cable. */
struct bench {
	bool pty;
	struct fscan_serial *link;
	struct fscan_mcu_model *model;
	/* pty only */
	char dir[64], path[96];
	int master;
};

static void pty_plug(struct bench *b)
{
	int slave;
	char name[64];
	assert_int_equal(openpty(&b->master, &slave, name, NULL, NULL), 0);
	close(slave); /* the link opens it by name, like a /dev/serial/by-id link */
	unlink(b->path);
	assert_int_equal(symlink(name, b->path), 0);
	assert_int_equal(fscan_mcu_model_start(b->master, &b->model), 0);
}

static void pty_unplug(struct bench *b)
{
	fscan_mcu_model_stop(b->model);
	b->model = NULL;
	close(b->master);
	b->master = -1;
	unlink(b->path);
}

static struct bench *bench_new(bool pty)
{
	struct bench *b = calloc(1, sizeof(*b));
	b->pty = pty;
	b->master = -1;
	if (pty) {
		snprintf(b->dir, sizeof(b->dir), "/tmp/fscan-serial-XXXXXX");
		assert_non_null(mkdtemp(b->dir));
		snprintf(b->path, sizeof(b->path), "%s/ttyMCU", b->dir);
		pty_plug(b);
		struct fscan_serial_config cfg = {.device = b->path, .baud = 115200};
		assert_int_equal(fscan_serial_create(&fscan_serial_termios_ops, &cfg, &b->link), 0);
	} else {
		static int n;
		char name[32];
		snprintf(name, sizeof(name), "fake-mcu-%d", n++);
		struct fscan_serial_config cfg = {.device = name};
		assert_int_equal(fscan_serial_create(&fscan_serial_fake_ops, &cfg, &b->link), 0);
		assert_int_equal(fscan_mcu_model_start(fscan_serial_fake_peer_fd(b->link), &b->model), 0);
	}
	return b;
}

static void bench_unplug(struct bench *b)
{
	if (b->pty) {
		pty_unplug(b);
	} else {
		assert_int_equal(fscan_serial_fake_unplug(b->link), 0);
		fscan_mcu_model_stop(b->model); /* its socket end is gone */
		b->model = NULL;
	}
}

static void bench_replug(struct bench *b)
{
	if (b->pty)
		pty_plug(b);
	else
		assert_int_equal(fscan_serial_fake_plug(b->link), 0);
}

/* After the link reconnected on its own: the fake's model must follow the new socket. */
static void bench_follow(struct bench *b)
{
	if (!b->pty && !b->model)
		assert_int_equal(fscan_mcu_model_start(fscan_serial_fake_peer_fd(b->link), &b->model), 0);
}

static void bench_free(struct bench *b)
{
	fscan_serial_destroy(b->link);
	fscan_mcu_model_stop(b->model);
	if (b->pty) {
		if (b->master >= 0)
			close(b->master);
		unlink(b->path);
		rmdir(b->dir);
	} else {
		/* leave the fake device plugged for the registry */
	}
	free(b);
}

/* ---- the contract ---- */

static void contract_hello_timing_status(bool pty)
{
	struct bench *b = bench_new(pty);
	struct fs_hello h;
	assert_int_equal(fscan_serial_hello(b->link, &h, T), 0);
	assert_int_equal(h.proto_version, FS_PROTO_VERSION);
	assert_int_equal(h.tick_hz, 1000000);
	struct fs_timing t;
	assert_int_equal(fscan_serial_get_timing(b->link, &t, T), 0);
	struct fs_timing d;
	fs_timing_default(&d);
	assert_memory_equal(&t, &d, sizeof(t));
	t.exposure_us = 4000;
	assert_int_equal(fscan_serial_set_timing(b->link, &t, T), 0);
	struct fs_timing back;
	assert_int_equal(fscan_serial_get_timing(b->link, &back, T), 0);
	assert_int_equal(back.exposure_us, 4000);
	/* Out of range: refused with the protocol's error, nothing changed. */
	t.exposure_us = FS_TIMING_EXPOSURE_MAX + 1;
	assert_int_equal(fscan_serial_set_timing(b->link, &t, T), -EREMOTEIO);
	assert_int_equal(fscan_serial_last_nack(b->link), FS_ERR_RANGE);
	struct fs_status s;
	assert_int_equal(fscan_serial_status(b->link, &s, T), 0);
	assert_int_equal(s.state, FS_STATE_IDLE);
	assert_int_equal(fscan_serial_last_nack(b->link), FS_ERR_NONE);
	bench_free(b);
}

static void contract_fire_and_report(bool pty)
{
	struct bench *b = bench_new(pty);
	assert_int_equal(fscan_serial_command(b->link, FS_CMD_ARM, T), 0);
	struct fs_status s;
	assert_int_equal(fscan_serial_status(b->link, &s, T), 0);
	assert_int_equal(s.state, FS_STATE_ARMED);
	assert_int_equal(fscan_serial_command(b->link, FS_CMD_FIRE, T), 0);
	struct fs_frame ev;
	assert_int_equal(fscan_serial_next_event(b->link, &ev, T), 0);
	while (ev.type == FS_EVT_BOOT) /* the fake's model greets first */
		assert_int_equal(fscan_serial_next_event(b->link, &ev, T), 0);
	assert_int_equal(ev.type, FS_EVT_REPORT);
	struct fs_report rep;
	assert_int_equal(fs_report_get(&ev, &rep), 0);
	assert_int_equal(rep.result, FS_REPORT_DONE);
	assert_int_equal(rep.trigger, FS_TRIGGER_HOST);
	assert_int_equal(rep.steps, FS_STEP__COUNT);
	assert_int_equal(rep.tick[FS_STEP_SHUT1_RISE], FS_TIMING_DEFAULT_PROJ_SETTLE);
	assert_int_equal(rep.lines_end & FS_LINES_LIGHT, 0);
	assert_int_equal(fscan_serial_command(b->link, FS_CMD_STATUS, T), -EINVAL); /* not a plain-ACK command */
	assert_int_equal(fscan_mcu_model_scans(b->model), 1);
	bench_free(b);
}

static void contract_button_event_while_requesting(bool pty)
{
	struct bench *b = bench_new(pty);
	assert_int_equal(fscan_serial_command(b->link, FS_CMD_ARM, T), 0);
	assert_int_equal(fscan_mcu_model_press(b->model), 0);
	/* A request made meanwhile still gets its answer; the events wait in the queue. */
	struct timespec ts = {0, 20 * 1000000L};
	nanosleep(&ts, NULL);
	struct fs_status s;
	assert_int_equal(fscan_serial_status(b->link, &s, T), 0);
	assert_int_equal(s.buttons, 1);
	assert_true(fscan_serial_pending(b->link));
	struct fs_frame ev;
	int buttons = 0, reports = 0;
	while (fscan_serial_next_event(b->link, &ev, 100) == 0) {
		if (ev.type == FS_EVT_BUTTON) {
			struct fs_button btn;
			assert_int_equal(fs_button_get(&ev, &btn), 0);
			assert_int_equal(btn.started, 1);
			buttons++;
		}
		if (ev.type == FS_EVT_REPORT) {
			struct fs_report rep;
			assert_int_equal(fs_report_get(&ev, &rep), 0);
			assert_int_equal(rep.trigger, FS_TRIGGER_BUTTON);
			reports++;
		}
	}
	assert_int_equal(buttons, 1);
	assert_int_equal(reports, 1);
	bench_free(b);
}

static void contract_hung_mcu_times_out(bool pty)
{
	struct bench *b = bench_new(pty);
	assert_int_equal(fscan_mcu_model_set_mute(b->model, true), 0);
	struct fs_hello h;
	assert_int_equal(fscan_serial_hello(b->link, &h, 50), -ETIMEDOUT);
	/* It comes back; the stale request is not mistaken for the new one. */
	assert_int_equal(fscan_mcu_model_set_mute(b->model, false), 0);
	assert_int_equal(fscan_serial_hello(b->link, &h, T), 0);
	assert_true(fscan_serial_connected(b->link));
	bench_free(b);
}

static void contract_unplug_and_replug(bool pty)
{
	struct bench *b = bench_new(pty);
	struct fs_hello h;
	assert_int_equal(fscan_serial_hello(b->link, &h, T), 0);
	bench_unplug(b);
	assert_int_equal(fscan_serial_hello(b->link, &h, T), -ENOTCONN);
	assert_false(fscan_serial_connected(b->link));
	assert_int_equal(fscan_serial_fd(b->link), -ENOTCONN);
	/* Still unplugged: fails at once, without waiting out the timeout. */
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	assert_int_equal(fscan_serial_hello(b->link, &h, T), -ENOTCONN);
	clock_gettime(CLOCK_MONOTONIC, &t1);
	assert_true(t1.tv_sec - t0.tv_sec < 1);
	bench_replug(b);
	/* The first call after the replug that needs the wire reopens the device. */
	fscan_serial_flush_input(b->link);
	struct fs_frame ev;
	int r = fscan_serial_next_event(b->link, &ev, 0);
	assert_true(r == -ETIMEDOUT || r == 0);
	bench_follow(b);
	assert_true(fscan_serial_connected(b->link));
	assert_int_equal(fscan_serial_hello(b->link, &h, T), 0);
	struct fscan_serial_stats st;
	fscan_serial_get_stats(b->link, &st);
	assert_int_equal(st.hangups, 1);
	assert_int_equal(st.reconnects, 1);
	bench_free(b);
}

/* Pulls the cable from another thread while the link waits (no cmocka asserts off the main
 * thread). */
static void *unplug_later(void *arg)
{
	struct bench *b = arg;
	struct timespec ts = {0, 50 * 1000000L};
	nanosleep(&ts, NULL);
	if (b->pty) {
		pty_unplug(b);
	} else {
		fscan_serial_fake_unplug(b->link);
		fscan_mcu_model_stop(b->model);
		b->model = NULL;
	}
	return NULL;
}

/* The cable goes while the link waits for an event (a report, say): the wait ends with
 * -ENOTCONN at once, not after its timeout. (The fake's unplug_on_fire relies on this.) */
static void contract_hangup_while_waiting(bool pty)
{
	struct bench *b = bench_new(pty);
	struct fs_hello h;
	assert_int_equal(fscan_serial_hello(b->link, &h, T), 0);
	/* The model can hang up mid-sequence only on a socket (the fake's peer). */
	if (pty)
		assert_int_equal(fscan_mcu_model_hangup_on_sequence(b->model), -ENOTSOCK);
	fscan_serial_flush_input(b->link);
	pthread_t t;
	assert_int_equal(pthread_create(&t, NULL, unplug_later, b), 0);
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	struct fs_frame ev;
	int r = fscan_serial_next_event(b->link, &ev, T);
	clock_gettime(CLOCK_MONOTONIC, &t1);
	assert_int_equal(pthread_join(t, NULL), 0);
	assert_int_equal(r, -ENOTCONN);
	long ms = (t1.tv_sec - t0.tv_sec) * 1000 + (t1.tv_nsec - t0.tv_nsec) / 1000000;
	assert_true(ms < T / 2);
	assert_false(fscan_serial_connected(b->link));
	bench_free(b);
}

static void test_fake_hello_timing_status(void **s) { (void)s; contract_hello_timing_status(false); }
static void test_pty_hello_timing_status(void **s) { (void)s; contract_hello_timing_status(true); }
static void test_fake_fire_and_report(void **s) { (void)s; contract_fire_and_report(false); }
static void test_pty_fire_and_report(void **s) { (void)s; contract_fire_and_report(true); }
static void test_fake_button_event(void **s) { (void)s; contract_button_event_while_requesting(false); }
static void test_pty_button_event(void **s) { (void)s; contract_button_event_while_requesting(true); }
static void test_fake_hung_mcu(void **s) { (void)s; contract_hung_mcu_times_out(false); }
static void test_pty_hung_mcu(void **s) { (void)s; contract_hung_mcu_times_out(true); }
static void test_fake_unplug(void **s) { (void)s; contract_unplug_and_replug(false); }
static void test_pty_unplug(void **s) { (void)s; contract_unplug_and_replug(true); }
static void test_fake_hangup_while_waiting(void **s) { (void)s; contract_hangup_while_waiting(false); }
static void test_pty_hangup_while_waiting(void **s) { (void)s; contract_hangup_while_waiting(true); }

/* ---- the fake device with the MCU attached ---- */

static void test_fake_device_with_mcu(void **s)
{
	(void)s;
	const char *dev = "fake-with-mcu";
	assert_int_equal(fscan_serial_fake_mcu_press(dev), -EINVAL); /* nothing attached yet */
	assert_int_equal(fscan_serial_fake_attach_mcu(NULL), -EINVAL);
	assert_int_equal(fscan_serial_fake_attach_mcu(dev), 0);
	assert_int_equal(fscan_serial_fake_mcu_press(dev), -ENOTCONN); /* no link connected */
	assert_int_equal(fscan_serial_fake_mcu_unplug_on_fire(dev), -ENOTCONN);
	struct fscan_serial_config cfg = {.device = dev};
	struct fscan_serial *link;
	assert_int_equal(fscan_serial_create(&fscan_serial_fake_ops, &cfg, &link), 0);
	assert_int_equal(fscan_serial_fake_attach_mcu(dev), -EBUSY);
	/* The firmware boots on the connection and answers as itself. */
	struct fs_frame ev;
	assert_int_equal(next_event_of(link, FS_EVT_BOOT, &ev, T), 0);
	struct fs_hello h;
	assert_int_equal(fscan_serial_hello(link, &h, T), 0);
	assert_int_equal(h.board, FS_BOARD_NATIVE);
	/* A host-fired sequence is counted; a press is the firmware's debounced press. */
	assert_int_equal(fscan_serial_command(link, FS_CMD_FIRE, T), 0);
	assert_int_equal(next_event_of(link, FS_EVT_REPORT, &ev, T), 0);
	assert_int_equal(fscan_serial_fake_mcu_scans(dev), 1);
	assert_int_equal(fscan_serial_fake_mcu_press(dev), 0);
	assert_int_equal(next_event_of(link, FS_EVT_BUTTON, &ev, T), 0);
	/* The link lost mid-sequence: the fire is acknowledged (the sequence started), then a
	 * hangup comes instead of the report, and the device stays unplugged. */
	assert_int_equal(fscan_serial_fake_mcu_unplug_on_fire(dev), 0);
	assert_int_equal(fscan_serial_command(link, FS_CMD_FIRE, T), 0);
	assert_int_equal(next_event_of(link, FS_EVT_REPORT, &ev, T), -ENOTCONN);
	assert_int_equal(fscan_serial_hello(link, &h, T), -ENOTCONN);
	assert_int_equal(fscan_serial_fake_mcu_press(dev), -ENOTCONN);
	assert_int_equal(fscan_serial_fake_mcu_scans(dev), 1); /* that one never completed */
	/* Plugged back: the next call reconnects to a freshly booted MCU. */
	assert_int_equal(fscan_serial_fake_device_plug(dev), 0);
	assert_int_equal(fscan_serial_hello(link, &h, T), 0);
	struct fs_status st;
	assert_int_equal(fscan_serial_status(link, &st, T), 0);
	assert_int_equal(st.state, FS_STATE_IDLE);
	assert_int_equal(st.scans, 0);
	/* The cable pulled while idle, and back. */
	assert_int_equal(fscan_serial_fake_device_unplug(dev), 0);
	assert_int_equal(fscan_serial_hello(link, &h, T), -ENOTCONN);
	assert_int_equal(fscan_serial_hello(link, &h, T), -ENOTCONN);
	assert_int_equal(fscan_serial_fake_device_plug(dev), 0);
	assert_int_equal(fscan_serial_hello(link, &h, T), 0);
	assert_int_equal(fscan_serial_command(link, FS_CMD_FIRE, T), 0);
	assert_int_equal(next_event_of(link, FS_EVT_REPORT, &ev, T), 0);
	assert_int_equal(fscan_serial_fake_mcu_scans(dev), 2); /* over every connection */
	struct fscan_serial_stats stats;
	fscan_serial_get_stats(link, &stats);
	assert_int_equal(stats.hangups, 2);
	assert_int_equal(stats.reconnects, 2);
	fscan_serial_destroy(link);
	/* The MCU stopped with the link (another model may start: one per process); a new attach
	 * counts from zero. */
	struct fscan_mcu_model *other;
	int fds[2];
	assert_int_equal(socketpair(AF_UNIX, SOCK_STREAM, 0, fds), 0);
	assert_int_equal(fscan_mcu_model_start(fds[1], &other), 0);
	fscan_mcu_model_stop(other);
	close(fds[0]);
	close(fds[1]);
	assert_int_equal(fscan_serial_fake_attach_mcu(dev), 0);
	assert_int_equal(fscan_serial_fake_mcu_scans(dev), 0);
	assert_int_equal(fscan_serial_fake_device_unplug("no-such-device"), -EINVAL);
}

/* ---- framing faults through the fake's raw peer ---- */

static struct fscan_serial *raw_link(void)
{
	static int n;
	char name[32];
	snprintf(name, sizeof(name), "raw-%d", n++);
	struct fscan_serial_config cfg = {.device = name};
	struct fscan_serial *link;
	assert_int_equal(fscan_serial_create(&fscan_serial_fake_ops, &cfg, &link), 0);
	return link;
}

static void test_garbage_and_bad_crc_skipped(void **s)
{
	(void)s;
	struct fscan_serial *link = raw_link();
	struct fs_frame f;
	fs_frame_init(&f, FS_EVT_BUTTON, 7);
	struct fs_button btn = {.started = 0, .count = 3};
	fs_button_put(&f, &btn);
	uint8_t good[FS_PROTO_MAX_FRAME];
	size_t len;
	assert_int_equal(fs_frame_encode(&f, good, sizeof(good), &len), 0);
	/* Line noise, then the frame with one byte flipped, then the frame intact. */
	uint8_t noise[] = {0x13, 0x37, 0x42};
	uint8_t bad[FS_PROTO_MAX_FRAME];
	memcpy(bad, good, len);
	bad[len / 2] ^= 0x01;
	if (bad[len / 2] == 0)
		bad[len / 2] = 0x55;
	assert_int_equal(fscan_serial_fake_peer_write(link, noise, sizeof(noise)), (ssize_t)sizeof(noise));
	assert_int_equal(fscan_serial_fake_peer_write(link, bad, len), (ssize_t)len);
	assert_int_equal(fscan_serial_fake_peer_write(link, good, len), (ssize_t)len);
	struct fs_frame got;
	assert_int_equal(fscan_serial_recv(link, &got, T), 0);
	assert_int_equal(got.type, FS_EVT_BUTTON);
	assert_int_equal(got.seq, 7);
	struct fs_button back;
	assert_int_equal(fs_button_get(&got, &back), 0);
	assert_int_equal(back.count, 3);
	struct fscan_serial_stats st;
	fscan_serial_get_stats(link, &st);
	assert_int_equal(st.frames_rx, 1);
	assert_true(st.bad_frames >= 2);
	assert_int_equal(fscan_serial_recv(link, &got, 20), -ETIMEDOUT);
	fscan_serial_destroy(link);
}

static void test_frame_split_across_reads(void **s)
{
	(void)s;
	struct fscan_serial *link = raw_link();
	struct fs_frame f;
	fs_frame_init(&f, FS_RSP_TIMING, 1);
	struct fs_timing t;
	fs_timing_default(&t);
	fs_timing_put(&f, &t);
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t len;
	assert_int_equal(fs_frame_encode(&f, buf, sizeof(buf), &len), 0);
	assert_int_equal(fscan_serial_fake_peer_write(link, buf, 5), 5);
	struct fs_frame got;
	assert_int_equal(fscan_serial_recv(link, &got, 20), -ETIMEDOUT);
	assert_int_equal(fscan_serial_fake_peer_write(link, buf + 5, len - 5), (ssize_t)(len - 5));
	assert_int_equal(fscan_serial_recv(link, &got, T), 0);
	struct fs_timing back;
	assert_int_equal(fs_timing_get(&got, &back), 0);
	assert_memory_equal(&back, &t, sizeof(t));
	fscan_serial_destroy(link);
}

static void test_request_assigns_seq_and_drops_stale(void **s)
{
	(void)s;
	struct fscan_serial *link = raw_link();
	/* Pre-load a stale ACK (seq 200) and an event; then answer the real request. */
	struct fs_frame stale, ev;
	fs_frame_init(&stale, FS_RSP_ACK, 200);
	fs_ack_put(&stale, FS_CMD_ARM);
	fs_frame_init(&ev, FS_EVT_FAULT, 9);
	struct fs_fault x = {.code = FS_FAULT_OVERRUN};
	fs_fault_put(&ev, &x);
	assert_int_equal(fscan_serial_fake_peer_send(link, &stale), 0);
	assert_int_equal(fscan_serial_fake_peer_send(link, &ev), 0);
	struct fs_frame cmd;
	fs_frame_init(&cmd, FS_CMD_ARM, 0);
	/* Answer from the peer side only after the request went out: send its ACK up front
	 * with the seq the link will pick (the first request gets 1). */
	struct fs_frame ack;
	fs_frame_init(&ack, FS_RSP_ACK, 1);
	fs_ack_put(&ack, FS_CMD_ARM);
	assert_int_equal(fscan_serial_fake_peer_send(link, &ack), 0);
	struct fs_frame resp;
	assert_int_equal(fscan_serial_request(link, &cmd, &resp, T), 0);
	assert_int_equal(cmd.seq, 1);
	assert_int_equal(resp.seq, 1);
	/* The link sent exactly that command. */
	struct fs_frame sent;
	assert_int_equal(fscan_serial_fake_peer_recv(link, &sent, T), 0);
	assert_int_equal(sent.type, FS_CMD_ARM);
	assert_int_equal(sent.seq, 1);
	/* The event that came meanwhile is queued. */
	struct fs_frame got;
	assert_int_equal(fscan_serial_next_event(link, &got, 0), 0);
	assert_int_equal(got.type, FS_EVT_FAULT);
	/* Responses are not commands. */
	assert_int_equal(fscan_serial_request(link, &ack, NULL, T), -EINVAL);
	fscan_serial_destroy(link);
}

static void test_create_errors(void **s)
{
	(void)s;
	struct fscan_serial *link = NULL;
	struct fscan_serial_config cfg = {.device = FSCAN_SERIAL_FAKE_MISSING_DEVICE};
	assert_int_equal(fscan_serial_create(&fscan_serial_fake_ops, &cfg, &link), -ENOENT);
	assert_null(link);
	cfg.device = "/nonexistent/tty";
	assert_int_equal(fscan_serial_create(&fscan_serial_termios_ops, &cfg, &link), -ENOENT);
	cfg.device = "/dev/null";
	assert_int_equal(fscan_serial_create(&fscan_serial_termios_ops, &cfg, &link), -ENOTTY);
	cfg.baud = 12345;
	assert_int_equal(fscan_serial_create(&fscan_serial_termios_ops, &cfg, &link), -EINVAL);
	assert_int_equal(fscan_serial_create(NULL, &cfg, &link), -EINVAL);
	fscan_serial_destroy(NULL);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_fake_hello_timing_status),
		cmocka_unit_test(test_pty_hello_timing_status),
		cmocka_unit_test(test_fake_fire_and_report),
		cmocka_unit_test(test_pty_fire_and_report),
		cmocka_unit_test(test_fake_button_event),
		cmocka_unit_test(test_pty_button_event),
		cmocka_unit_test(test_fake_hung_mcu),
		cmocka_unit_test(test_pty_hung_mcu),
		cmocka_unit_test(test_fake_unplug),
		cmocka_unit_test(test_pty_unplug),
		cmocka_unit_test(test_fake_hangup_while_waiting),
		cmocka_unit_test(test_pty_hangup_while_waiting),
		cmocka_unit_test(test_fake_device_with_mcu),
		cmocka_unit_test(test_garbage_and_bad_crc_skipped),
		cmocka_unit_test(test_frame_split_across_reads),
		cmocka_unit_test(test_request_assigns_seq_and_drops_stale),
		cmocka_unit_test(test_create_errors),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
