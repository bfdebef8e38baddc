/*
 * The lm3s6965evb firmware image in QEMU with deterministic virtual time
 * (-icount shift=5,sleep=off). The test is the host: it talks to UART0 over a unix socket
 * with the shared protocol codec, sets a timing, fires, presses the button through the
 * board's UART debug command, hangs the main loop (another debug command) and sees the
 * watchdog bring it back in FAULT, and then checks what the emulator saw: QEMU's own trace of
 * the GPIO port (pl061_set_output) interleaved with its SysTick ticks (systick_timer_tick,
 * the firmware's 100 kHz clock). From that trace: every shutter edge of the 4 lines on the
 * same tick, the order and widths configured, the lights off at the end.
 *
 * Skips (77) when qemu-system-arm is not installed; fails when the image is missing.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>

#include "fw_client.h"
#include "protocol/protocol.h"

#define QEMU "qemu-system-arm"
#define TIMEOUT_MS 10000
#define MAX_EVENTS 4096

static char tmpdir[64];
static char sock_path[100];
static char trace_path[128];
static char log_path[128];
static char elf_path[512];
static pid_t qemu_pid = -1;
static struct fwc client;
static struct fs_hello hello;
static struct fs_report reports[2];
static int n_reports;

/* Timing used by the test: multiples of 10 us, so every width is a whole number of ticks. */
static const struct fs_timing timing = {
	.proj_settle_us = 5000,
	.exposure_us = 3330,
	.proj_hold_us = 120,
	.flash_delay_us = 8000,
	.flash_settle_us = 700,
	.flash_exposure_us = 1500,
	.flash_hold_us = 50,
};

static bool in_path(const char *prog)
{
	const char *path = getenv("PATH");
	char buf[4096];
	if (!path)
		return false;
	snprintf(buf, sizeof(buf), "%s", path);
	for (char *save = NULL, *d = strtok_r(buf, ":", &save); d; d = strtok_r(NULL, ":", &save)) {
		char full[4200];
		snprintf(full, sizeof(full), "%s/%s", d, prog);
		if (access(full, X_OK) == 0)
			return true;
	}
	return false;
}

static void dump_log(void)
{
	char line[512];
	FILE *f = fopen(log_path, "r");
	if (!f)
		return;
	while (fgets(line, sizeof(line), f))
		fprintf(stderr, "qemu: %s", line);
	fclose(f);
}

static void stop_qemu(void)
{
	if (qemu_pid > 0) {
		kill(qemu_pid, SIGTERM);
		waitpid(qemu_pid, NULL, 0);
		qemu_pid = -1;
	}
	if (client.fd > 0) {
		close(client.fd);
		client.fd = -1;
	}
}

static int start_qemu(void **state)
{
	(void)state;
	snprintf(tmpdir, sizeof(tmpdir), "/tmp/facescan-qemu-XXXXXX");
	if (!mkdtemp(tmpdir))
		return -1;
	snprintf(sock_path, sizeof(sock_path), "%s/uart0.sock", tmpdir);
	snprintf(trace_path, sizeof(trace_path), "%s/trace.log", tmpdir);
	snprintf(log_path, sizeof(log_path), "%s/qemu.log", tmpdir);

	qemu_pid = fork();
	if (qemu_pid < 0)
		return -1;
	if (qemu_pid == 0) {
		char chardev[256];
		int log = open(log_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		if (log >= 0) {
			dup2(log, STDOUT_FILENO);
			dup2(log, STDERR_FILENO);
		}
		snprintf(chardev, sizeof(chardev), "socket,id=u0,path=%s,server=on,wait=on",
			 sock_path);
		execlp(QEMU, QEMU, "-M", "lm3s6965evb", "-nographic", "-monitor", "none",
		       "-icount", "shift=5,sleep=off", "-kernel", elf_path, "-chardev", chardev,
		       "-serial", "chardev:u0", "-trace", "pl061_set_output", "-trace",
		       "systick_timer_tick", "-D", trace_path, (char *)NULL);
		_exit(127);
	}

	/* wait=on: the guest is held until we connect, so no byte is lost. */
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	struct sockaddr_un sa = { .sun_family = AF_UNIX };
	snprintf(sa.sun_path, sizeof(sa.sun_path), "%s", sock_path);
	int64_t deadline = fwc_now_ms() + TIMEOUT_MS;
	while (connect(fd, (struct sockaddr *)&sa, sizeof(sa)) < 0) {
		if (fwc_now_ms() > deadline || waitpid(qemu_pid, NULL, WNOHANG) != 0) {
			fprintf(stderr, "cannot connect to QEMU's UART at %s\n", sock_path);
			dump_log();
			close(fd);
			return -1;
		}
		usleep(20000);
	}
	fwc_init(&client, fd);
	return 0;
}

static int cleanup(void **state)
{
	(void)state;
	stop_qemu();
	if (getenv("FACESCAN_KEEP_TRACE")) {
		fprintf(stderr, "trace kept in %s\n", tmpdir);
		return 0;
	}
	unlink(sock_path);
	unlink(trace_path);
	unlink(log_path);
	rmdir(tmpdir);
	return 0;
}

static uint32_t ticks_of(uint32_t us)
{
	return (uint32_t)(((uint64_t)us * hello.tick_hz + 500000u) / 1000000u);
}

/* ---- over the UART ----------------------------------------------------------------------- */

static void test_boot_and_hello(void **state)
{
	(void)state;
	struct fs_frame f;
	struct fs_boot b;
	assert_int_equal(fwc_wait_event(&client, FS_EVT_BOOT, &f, TIMEOUT_MS), 1);
	assert_int_equal(fs_boot_get(&f, &b), 0);
	assert_int_equal(b.proto_version, FS_PROTO_VERSION);

	assert_int_equal(fwc_cmd(&client, FS_CMD_HELLO, &f, TIMEOUT_MS), 1);
	assert_int_equal(f.type, FS_RSP_HELLO);
	assert_int_equal(fs_hello_get(&f, &hello), 0);
	assert_int_equal(hello.proto_version, FS_PROTO_VERSION);
	assert_int_equal(hello.board, FS_BOARD_LM3S6965EVB);
	assert_int_equal(hello.tick_hz, 100000);
}

static void test_bad_frames_are_nacked(void **state)
{
	(void)state;
	struct fs_frame f, r;
	/* Line noise, then a frame with a broken CRC: two NACKs, nothing else changes. */
	const uint8_t noise[] = { 0x13, 0x77, 0xf0, 0x01 };
	assert_int_equal(write(client.fd, noise, sizeof(noise)), (ssize_t)sizeof(noise));
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t n = 0;
	fs_frame_init(&f, FS_CMD_FIRE, 99);
	assert_int_equal(fs_frame_encode(&f, buf, sizeof(buf), &n), 0);
	buf[2] ^= 0x40;
	assert_int_equal(write(client.fd, buf, n), (ssize_t)n);
	int nacks = 0;
	while (nacks < 2) {
		assert_int_equal(fwc_recv(&client, &r, TIMEOUT_MS), 1);
		if (r.type == FS_RSP_NACK)
			nacks++;
	}
	struct fs_nack nk;
	assert_int_equal(fs_nack_get(&r, &nk), 0);
	assert_int_equal(nk.err, FS_ERR_CRC);

	struct fs_status s;
	assert_int_equal(fwc_cmd(&client, FS_CMD_STATUS, &f, TIMEOUT_MS), 1);
	assert_int_equal(fs_status_get(&f, &s), 0);
	assert_int_equal(s.state, FS_STATE_IDLE);
	assert_int_equal(s.lines, 0);
	assert_int_equal(s.rx_errors, 2);
}

static void test_set_timing_and_fire(void **state)
{
	(void)state;
	struct fs_frame f, r;
	struct fs_timing got;
	fs_frame_init(&f, FS_CMD_SET_TIMING, 0);
	fs_timing_put(&f, &timing);
	assert_int_equal(fwc_transact(&client, &f, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	assert_int_equal(fwc_cmd(&client, FS_CMD_GET_TIMING, &r, TIMEOUT_MS), 1);
	assert_int_equal(fs_timing_get(&r, &got), 0);
	assert_memory_equal(&got, &timing, sizeof(timing));

	assert_int_equal(fwc_cmd(&client, FS_CMD_FIRE, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	assert_int_equal(fwc_wait_event(&client, FS_EVT_REPORT, &f, TIMEOUT_MS), 1);
	struct fs_report *rep = &reports[n_reports++];
	assert_int_equal(fs_report_get(&f, rep), 0);
	assert_int_equal(rep->result, FS_REPORT_DONE);
	assert_int_equal(rep->trigger, FS_TRIGGER_HOST);
	assert_int_equal(rep->steps, FS_STEP__COUNT);
	assert_int_equal(rep->lines_end, 0);
}

static void test_button_starts_scan_when_armed(void **state)
{
	(void)state;
	struct fs_frame f, r;
	assert_int_equal(fwc_cmd(&client, FS_CMD_ARM, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	fs_frame_init(&f, FS_CMD_DEBUG_BUTTON, 0);
	fs_debug_button_put(&f, 50);
	assert_int_equal(fwc_transact(&client, &f, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);

	struct fs_button b;
	assert_int_equal(fwc_wait_event(&client, FS_EVT_BUTTON, &f, TIMEOUT_MS), 1);
	assert_int_equal(fs_button_get(&f, &b), 0);
	assert_int_equal(b.started, 1);
	assert_int_equal(fwc_wait_event(&client, FS_EVT_REPORT, &f, TIMEOUT_MS), 1);
	struct fs_report *rep = &reports[n_reports++];
	assert_int_equal(fs_report_get(&f, rep), 0);
	assert_int_equal(rep->result, FS_REPORT_DONE);
	assert_int_equal(rep->trigger, FS_TRIGGER_BUTTON);

	struct fs_status s;
	assert_int_equal(fwc_cmd(&client, FS_CMD_STATUS, &r, TIMEOUT_MS), 1);
	assert_int_equal(fs_status_get(&r, &s), 0);
	assert_int_equal(s.scans, 2);
	assert_int_equal(s.lines & FS_LINES_LIGHT, 0);
	assert_int_equal(client.bad_frames, 0);
}

static void test_watchdog_recovers_hung_loop(void **state)
{
	(void)state;
	struct fs_frame f, r;
	/* The main loop stops kicking: the WDT interrupt darkens the lines, then it resets. */
	assert_int_equal(fwc_cmd(&client, FS_CMD_DEBUG_HANG, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	struct fs_boot b;
	struct fs_fault x;
	assert_int_equal(fwc_wait_event(&client, FS_EVT_BOOT, &f, TIMEOUT_MS), 1);
	assert_int_equal(fs_boot_get(&f, &b), 0);
	assert_int_equal(b.reset_cause, FS_RESET_WATCHDOG);
	assert_int_equal(fwc_wait_event(&client, FS_EVT_FAULT, &f, TIMEOUT_MS), 1);
	assert_int_equal(fs_fault_get(&f, &x), 0);
	assert_int_equal(x.code, FS_FAULT_WATCHDOG);
	assert_int_equal(x.lines, 0);

	struct fs_status s;
	assert_int_equal(fwc_cmd(&client, FS_CMD_STATUS, &r, TIMEOUT_MS), 1);
	assert_int_equal(fs_status_get(&r, &s), 0);
	assert_int_equal(s.state, FS_STATE_FAULT);
	assert_int_equal(s.reset_cause, FS_RESET_WATCHDOG);
	assert_int_equal(s.lines, 0);
	assert_int_equal(fwc_cmd(&client, FS_CMD_FIRE, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_NACK);
	assert_int_equal(fwc_cmd(&client, FS_CMD_CLEAR_FAULT, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	assert_int_equal(fwc_cmd(&client, FS_CMD_STATUS, &r, TIMEOUT_MS), 1);
	assert_int_equal(fs_status_get(&r, &s), 0);
	assert_int_equal(s.state, FS_STATE_IDLE);
}

/* ---- from the emulator's trace ----------------------------------------------------------- */

struct edge {
	uint64_t tick;  /* SysTick ticks seen before this edge */
	size_t index;   /* position among all GPIO events of the port */
	int line;
	int level;
};

static struct edge edges[MAX_EVENTS];
static size_t n_edges;

static void parse_trace(void)
{
	char line[256], dev[128], lines_dev[128] = "";
	static struct edge all[MAX_EVENTS];
	static char devs[MAX_EVENTS][128];
	size_t n = 0;
	uint64_t tick = 0;
	FILE *f = fopen(trace_path, "r");
	assert_non_null(f);
	while (fgets(line, sizeof(line), f)) {
		int l, v;
		if (!strncmp(line, "systick_timer_tick", 18)) {
			tick++;
		} else if (sscanf(line, "pl061_set_output %127s setting output %d to %d", dev, &l,
				  &v) == 3) {
			assert_true(n < MAX_EVENTS);
			all[n] = (struct edge){ tick, n, l, v };
			snprintf(devs[n], sizeof(devs[n]), "%s", dev);
			/* The LED port only ever moves pin 0; the lines port moves 0..7. */
			if (l > 0)
				snprintf(lines_dev, sizeof(lines_dev), "%s", dev);
			n++;
		}
	}
	fclose(f);
	assert_true(lines_dev[0] != 0);
	n_edges = 0;
	for (size_t i = 0; i < n; i++)
		if (!strcmp(devs[i], lines_dev))
			edges[n_edges++] = all[i];
}

/* The k-th edge to `level` on `line`, or NULL. */
static const struct edge *nth_edge(int line, int level, int k)
{
	for (size_t i = 0; i < n_edges; i++)
		if (edges[i].line == line && edges[i].level == level && k-- == 0)
			return &edges[i];
	return NULL;
}

static void test_trace_lockstep_order_widths(void **state)
{
	(void)state;
	stop_qemu(); /* flushes the trace */
	parse_trace();
	assert_int_equal(n_reports, 2);

	/* Two sequences: per sequence 3 projector + 1 flash lines on and off, and 4 shutters
	 * pulsed twice: (4 + 8) * 2 edges each. */
	assert_int_equal(n_edges, 2 * 2 * (4 + 8));

	uint64_t max_skew = 0;
	for (int seq = 0; seq < 2; seq++) {
		const struct fs_report *rep = &reports[seq];
		/* Emulator ticks of the 8 steps, from the lines that define each one. */
		const struct edge *p_on = nth_edge(0, 1, seq), *p_off = nth_edge(0, 0, seq);
		const struct edge *f_on = nth_edge(3, 1, seq), *f_off = nth_edge(3, 0, seq);
		assert_non_null(p_on);
		assert_non_null(p_off);
		assert_non_null(f_on);
		assert_non_null(f_off);
		for (int l = 1; l <= 2; l++) {
			assert_int_equal(nth_edge(l, 1, seq)->tick, p_on->tick);
			assert_int_equal(nth_edge(l, 0, seq)->tick, p_off->tick);
		}
		for (int pulse = 0; pulse < 2; pulse++) {
			const struct edge *rise[4], *fall[4];
			for (int s = 0; s < 4; s++) {
				rise[s] = nth_edge(4 + s, 1, seq * 2 + pulse);
				fall[s] = nth_edge(4 + s, 0, seq * 2 + pulse);
				assert_non_null(rise[s]);
				assert_non_null(fall[s]);
			}
			/* Skew: spread of the 4 lines' edge ticks. One write: adjacent events too. */
			for (int s = 1; s < 4; s++) {
				uint64_t dr = rise[s]->tick > rise[0]->tick ? rise[s]->tick - rise[0]->tick
									     : rise[0]->tick - rise[s]->tick;
				uint64_t df = fall[s]->tick > fall[0]->tick ? fall[s]->tick - fall[0]->tick
									     : fall[0]->tick - fall[s]->tick;
				max_skew = dr > max_skew ? dr : max_skew;
				max_skew = df > max_skew ? df : max_skew;
				assert_int_equal(rise[s]->index, rise[0]->index + (size_t)s);
				assert_int_equal(fall[s]->index, fall[0]->index + (size_t)s);
			}
			for (int s = 0; s < 4; s++)
				assert_int_equal(fall[s]->tick - rise[s]->tick,
						 ticks_of(pulse == 0 ? timing.exposure_us
								     : timing.flash_exposure_us));
		}
		const struct edge *s1 = nth_edge(4, 1, seq * 2), *s1f = nth_edge(4, 0, seq * 2);
		const struct edge *s2 = nth_edge(4, 1, seq * 2 + 1), *s2f = nth_edge(4, 0, seq * 2 + 1);
		/* Order and widths, in the emulator's ticks. */
		assert_int_equal(s1->tick - p_on->tick, ticks_of(timing.proj_settle_us));
		assert_int_equal(p_off->tick - s1f->tick, ticks_of(timing.proj_hold_us));
		assert_int_equal(f_on->tick - p_off->tick, ticks_of(timing.flash_delay_us));
		assert_int_equal(s2->tick - f_on->tick, ticks_of(timing.flash_settle_us));
		assert_int_equal(f_off->tick - s2f->tick, ticks_of(timing.flash_hold_us));
		assert_true(p_on->index < s1->index && s1f->index < p_off->index &&
			    p_off->index < f_on->index && s2f->index < f_off->index);

		/* The firmware's report agrees with the emulator, tick for tick. */
		const uint64_t at[FS_STEP__COUNT] = { p_on->tick, s1->tick, s1f->tick, p_off->tick,
						      f_on->tick, s2->tick, s2f->tick, f_off->tick };
		for (int i = 0; i < FS_STEP__COUNT; i++)
			assert_int_equal(rep->tick[i] - rep->tick[0], at[i] - at[0]);
		print_message("sequence %d: P on @%llu, shutters %u+%u ticks, flash %u ticks\n", seq,
			      (unsigned long long)p_on->tick, (unsigned)(s1f->tick - s1->tick),
			      (unsigned)(s2f->tick - s2->tick), (unsigned)(f_off->tick - f_on->tick));
	}
	print_message("shutter skew: %llu ticks over %d edges x 4 lines (tick = %u us)\n",
		      (unsigned long long)max_skew, 8, 1000000u / hello.tick_hz);
	assert_int_equal(max_skew, 0);

	/* Lights off at the end: the last level of lines 0..3 is low. */
	for (int l = 0; l < 8; l++) {
		int level = 0;
		for (size_t i = 0; i < n_edges; i++)
			if (edges[i].line == l)
				level = edges[i].level;
		assert_int_equal(level, 0);
	}
}

int main(void)
{
	if (!in_path(QEMU)) {
		fprintf(stderr, "test_qemu: %s not installed (apt-get install qemu-system-arm)\n", QEMU);
		return 77;
	}
	const char *build = getenv("FACESCAN_BUILD");
	snprintf(elf_path, sizeof(elf_path), "%s/firmware/lm3s6965evb/facescan-fw.elf",
		 build ? build : "build");
	if (access(elf_path, R_OK) != 0) {
		fprintf(stderr, "test_qemu: firmware image %s missing (make firmware)\n", elf_path);
		return 1;
	}
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_boot_and_hello),
		cmocka_unit_test(test_bad_frames_are_nacked),
		cmocka_unit_test(test_set_timing_and_fire),
		cmocka_unit_test(test_button_starts_scan_when_armed),
		cmocka_unit_test(test_watchdog_recovers_hung_loop),
		cmocka_unit_test(test_trace_lockstep_order_widths),
	};
	return cmocka_run_group_tests(tests, start_qemu, cleanup);
}
