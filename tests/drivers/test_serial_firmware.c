/* The termios serial driver against the real firmware core: facescan-fw-native (the firmware
 * on its native board, behind a pty) is started as a child, and the driver greets it, sets the
 * timing, fires a sequence and reads the report, presses the button, then survives the MCU
 * going away and coming back (reconnect). The binary comes from $FACESCAN_BIN (set by make
 * test), else build/asan/bin. */
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
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "facescan/serial.h"
#include "serial_helpers.h"

#define T 2000

static char fw_path[512];
static char dir[64], link_path[128];

static pid_t start_firmware(void)
{
	unlink(link_path);
	pid_t pid = fork();
	if (pid == 0) {
		int null = open("/dev/null", O_WRONLY);
		dup2(null, STDOUT_FILENO);
		execl(fw_path, fw_path, "--link", link_path, (char *)NULL);
		_exit(127);
	}
	/* Ready when the symlink to its pty appears. */
	for (int i = 0; i < 500; i++) {
		struct stat st;
		if (lstat(link_path, &st) == 0)
			return pid;
		struct timespec ts = {0, 10 * 1000000L};
		nanosleep(&ts, NULL);
	}
	kill(pid, SIGKILL);
	waitpid(pid, NULL, 0);
	fail_msg("firmware did not create %s", link_path);
	return -1;
}

static void stop_firmware(pid_t pid)
{
	kill(pid, SIGTERM);
	int status;
	assert_int_equal(waitpid(pid, &status, 0), pid);
}

static void test_firmware_session(void **state)
{
	(void)state;
	pid_t fw = start_firmware();
	struct fscan_serial_config cfg = {.device = link_path, .baud = 115200};
	struct fscan_serial *link;
	assert_int_equal(fscan_serial_create(&fscan_serial_termios_ops, &cfg, &link), 0);

	struct fs_hello h;
	assert_int_equal(fscan_serial_hello(link, &h, T), 0);
	assert_int_equal(h.proto_version, FS_PROTO_VERSION);
	assert_int_equal(h.board, FS_BOARD_NATIVE);
	printf("firmware %u.%u, board %u, tick %u Hz\n", h.fw_major, h.fw_minor, h.board, h.tick_hz);

	struct fs_timing t;
	fs_timing_default(&t);
	t.exposure_us = 5000;
	assert_int_equal(fscan_serial_set_timing(link, &t, T), 0);
	struct fs_timing back;
	assert_int_equal(fscan_serial_get_timing(link, &back, T), 0);
	assert_int_equal(back.exposure_us, 5000);
	t.exposure_us = FS_TIMING_EXPOSURE_MAX + 1;
	assert_int_equal(fscan_serial_set_timing(link, &t, T), -EREMOTEIO);
	assert_int_equal(fscan_serial_last_nack(link), FS_ERR_RANGE);

	/* A host-fired sequence: ACK, then the report with the steps at the set timing. */
	assert_int_equal(fscan_serial_command(link, FS_CMD_FIRE, T), 0);
	struct fs_frame ev;
	assert_int_equal(next_event_of(link, FS_EVT_REPORT, &ev, T), 0);
	struct fs_report rep;
	assert_int_equal(fs_report_get(&ev, &rep), 0);
	assert_int_equal(rep.result, FS_REPORT_DONE);
	assert_int_equal(rep.trigger, FS_TRIGGER_HOST);
	assert_int_equal(rep.steps, FS_STEP__COUNT);
	uint64_t us = (uint64_t)(rep.tick[FS_STEP_SHUT1_FALL] - rep.tick[FS_STEP_SHUT1_RISE]) * 1000000u / h.tick_hz;
	printf("first shutter pulse: %llu us (set 5000)\n", (unsigned long long)us);
	assert_true(us >= 4900 && us <= 5100);
	assert_int_equal(rep.lines_end & FS_LINES_LIGHT, 0);

	/* The booth button (emulated board) while armed starts a scan. */
	assert_int_equal(fscan_serial_command(link, FS_CMD_ARM, T), 0);
	struct fs_frame cmd;
	fs_frame_init(&cmd, FS_CMD_DEBUG_BUTTON, 0);
	fs_debug_button_put(&cmd, 100);
	assert_int_equal(fscan_serial_request(link, &cmd, NULL, T), 0);
	assert_int_equal(next_event_of(link, FS_EVT_BUTTON, &ev, T), 0);
	struct fs_button btn;
	assert_int_equal(fs_button_get(&ev, &btn), 0);
	assert_int_equal(btn.started, 1);
	assert_int_equal(next_event_of(link, FS_EVT_REPORT, &ev, T), 0);
	assert_int_equal(fs_report_get(&ev, &rep), 0);
	assert_int_equal(rep.trigger, FS_TRIGGER_BUTTON);

	/* The MCU goes away (unplugged): the driver says so, quickly, and keeps saying so. */
	stop_firmware(fw);
	assert_int_equal(fscan_serial_hello(link, &h, T), -ENOTCONN);
	assert_false(fscan_serial_connected(link));
	assert_int_equal(fscan_serial_hello(link, &h, T), -ENOTCONN);
	/* It comes back on the same path: the next call reconnects. */
	fw = start_firmware();
	assert_int_equal(fscan_serial_hello(link, &h, T), 0);
	struct fscan_serial_stats st;
	fscan_serial_get_stats(link, &st);
	assert_int_equal(st.hangups, 1);
	assert_int_equal(st.reconnects, 1);
	printf("frames rx %llu tx %llu bad %llu\n", (unsigned long long)st.frames_rx,
	       (unsigned long long)st.frames_tx, (unsigned long long)st.bad_frames);

	fscan_serial_destroy(link);
	stop_firmware(fw);
}

int main(void)
{
	const char *bin = getenv("FACESCAN_BIN");
	snprintf(fw_path, sizeof(fw_path), "%s/facescan-fw-native", bin ? bin : "build/asan/bin");
	if (access(fw_path, X_OK) < 0) {
		fprintf(stderr, "test_serial_firmware: %s not built (make firmware / make tests)\n", fw_path);
		return 1;
	}
	snprintf(dir, sizeof(dir), "/tmp/fscan-fw-XXXXXX");
	if (!mkdtemp(dir))
		return 1;
	snprintf(link_path, sizeof(link_path), "%s/ttyMCU", dir);
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_firmware_session),
	};
	int r = cmocka_run_group_tests(tests, NULL, NULL);
	unlink(link_path);
	rmdir(dir);
	return r;
}
