/*
 * facescan-fw-native, the firmware on the simulated board behind a pty (the daemon's
 * fallback where QEMU is missing): a host opens the pty, says hello, sets timing, fires and
 * gets an exact report; SIGUSR1 presses the button; SIGUSR2 resets it; SIGTERM ends it and
 * removes its link.
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
#include <sys/stat.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <cmocka.h>

#include "fw_client.h"
#include "protocol/protocol.h"

#define TIMEOUT_MS 5000

static pid_t pid = -1;
static char link_path[64];
static char tmpdir[48];
static struct fwc client;

static int start(void **state)
{
	(void)state;
	char bin[512];
	const char *dir = getenv("FACESCAN_BIN");
	snprintf(bin, sizeof(bin), "%s/facescan-fw-native", dir ? dir : "build/bin");
	snprintf(tmpdir, sizeof(tmpdir), "/tmp/facescan-fwn-XXXXXX");
	if (!mkdtemp(tmpdir))
		return -1;
	snprintf(link_path, sizeof(link_path), "%s/tty", tmpdir);

	int out[2];
	if (pipe(out) < 0)
		return -1;
	pid = fork();
	if (pid == 0) {
		dup2(out[1], STDOUT_FILENO);
		close(out[0]);
		execl(bin, bin, "--link", link_path, (char *)NULL);
		_exit(127);
	}
	close(out[1]);
	char path[256] = "";
	size_t n = 0;
	while (n + 1 < sizeof(path)) {
		ssize_t r = read(out[0], path + n, 1);
		if (r <= 0 || path[n] == '\n')
			break;
		n++;
	}
	path[n] = 0;
	close(out[0]);
	if (n == 0) {
		fprintf(stderr, "%s printed no pty path\n", bin);
		return -1;
	}
	/* The printed path and the link name the same pty. */
	char target[256];
	ssize_t tl = readlink(link_path, target, sizeof(target) - 1);
	if (tl <= 0)
		return -1;
	target[tl] = 0;
	if (strcmp(target, path) != 0)
		return -1;

	int fd = open(link_path, O_RDWR | O_NOCTTY | O_CLOEXEC);
	struct termios tio;
	if (fd < 0 || tcgetattr(fd, &tio) < 0)
		return -1;
	cfmakeraw(&tio);
	tcsetattr(fd, TCSANOW, &tio);
	fwc_init(&client, fd);
	return 0;
}

static int stop(void **state)
{
	(void)state;
	if (client.fd > 0)
		close(client.fd);
	if (pid > 0) {
		kill(pid, SIGKILL);
		waitpid(pid, NULL, 0);
	}
	unlink(link_path);
	rmdir(tmpdir);
	return 0;
}

static void test_hello_and_boot(void **state)
{
	(void)state;
	struct fs_frame f;
	struct fs_hello h;
	/* The BOOT event was sent before anyone listened; ask for what matters instead. */
	assert_int_equal(fwc_cmd(&client, FS_CMD_HELLO, &f, TIMEOUT_MS), 1);
	assert_int_equal(fs_hello_get(&f, &h), 0);
	assert_int_equal(h.board, FS_BOARD_NATIVE);
	assert_int_equal(h.tick_hz, 1000000);
	assert_int_equal(h.proto_version, FS_PROTO_VERSION);
}

/* Sets the timing and fires with it: both acknowledged. */
static void fire_with(const struct fs_timing *t)
{
	struct fs_frame f, r;
	fs_frame_init(&f, FS_CMD_SET_TIMING, 0);
	fs_timing_put(&f, t);
	assert_int_equal(fwc_transact(&client, &f, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	assert_int_equal(fwc_cmd(&client, FS_CMD_FIRE, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
}

static void test_fire_exact_report(void **state)
{
	(void)state;
	struct fs_frame f;
	struct fs_timing t;
	fs_timing_default(&t);
	t.exposure_us = 4000;
	t.flash_delay_us = 9000;
	fire_with(&t);
	assert_int_equal(fwc_wait_event(&client, FS_EVT_REPORT, &f, TIMEOUT_MS), 1);
	struct fs_report rep;
	assert_int_equal(fs_report_get(&f, &rep), 0);
	assert_int_equal(rep.result, FS_REPORT_DONE);
	assert_int_equal(rep.steps, FS_STEP__COUNT);
	assert_int_equal(rep.lines_end, 0);
	/* Virtual time: the widths are exact whatever the host's scheduling. */
	assert_int_equal(rep.tick[FS_STEP_SHUT1_RISE] - rep.tick[FS_STEP_PROJ_ON], t.proj_settle_us);
	assert_int_equal(rep.tick[FS_STEP_SHUT1_FALL] - rep.tick[FS_STEP_SHUT1_RISE], 4000);
	assert_int_equal(rep.tick[FS_STEP_FLASH_ON] - rep.tick[FS_STEP_PROJ_OFF], 9000);
	assert_int_equal(rep.lines[FS_STEP_SHUT2_RISE], FS_LINE_FLASH | FS_LINES_SHUT);
}

static void test_sigusr1_presses_button(void **state)
{
	(void)state;
	struct fs_frame f;
	struct fs_button b;
	assert_int_equal(kill(pid, SIGUSR1), 0);
	assert_int_equal(fwc_wait_event(&client, FS_EVT_BUTTON, &f, TIMEOUT_MS), 1);
	assert_int_equal(fs_button_get(&f, &b), 0);
	assert_int_equal(b.started, 0); /* not armed: reported only */
	assert_int_equal(b.count, 1);
	usleep(300000); /* let the 100 ms press end, or the next press is the same press */
}

static void test_debug_button_when_armed(void **state)
{
	(void)state;
	struct fs_frame f, r;
	assert_int_equal(fwc_cmd(&client, FS_CMD_ARM, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	fs_frame_init(&f, FS_CMD_DEBUG_BUTTON, 0);
	fs_debug_button_put(&f, 60);
	assert_int_equal(fwc_transact(&client, &f, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	assert_int_equal(fwc_wait_event(&client, FS_EVT_REPORT, &f, TIMEOUT_MS), 1);
	struct fs_report rep;
	assert_int_equal(fs_report_get(&f, &rep), 0);
	assert_int_equal(rep.trigger, FS_TRIGGER_BUTTON);
	assert_int_equal(rep.result, FS_REPORT_DONE);
}

/* SIGUSR2 is the reset pin mid-sequence (the soak's MCU reset): the lines go dark at once,
 * the core boots again (EVT_BOOT, cause pin) and serves the next command. */
static void test_sigusr2_resets_mid_sequence(void **state)
{
	(void)state;
	struct fs_frame f, r;
	struct fs_timing t;
	fs_timing_default(&t);
	t.proj_settle_us = 400000;
	fire_with(&t);
	usleep(100000); /* projectors on, shutters not yet */
	assert_int_equal(kill(pid, SIGUSR2), 0);
	/* The power-on EVT_BOOT may still wait unread in the pty: the reset's is the next one. */
	struct fs_boot b = {FS_RESET_POWER, 0};
	for (int i = 0; i < 2 && b.reset_cause != FS_RESET_PIN; i++) {
		assert_int_equal(fwc_wait_event(&client, FS_EVT_BOOT, &f, TIMEOUT_MS), 1);
		assert_int_equal(fs_boot_get(&f, &b), 0);
	}
	assert_int_equal(b.reset_cause, FS_RESET_PIN);
	assert_int_equal(fwc_cmd(&client, FS_CMD_STATUS, &r, TIMEOUT_MS), 1);
	struct fs_status st;
	assert_int_equal(fs_status_get(&r, &st), 0);
	assert_int_equal(st.lines, 0);
	assert_int_equal(st.state, FS_STATE_IDLE);
	/* The reset forgot the timing: the default again, and a fire completes. */
	assert_int_equal(fwc_cmd(&client, FS_CMD_FIRE, &r, TIMEOUT_MS), 1);
	assert_int_equal(r.type, FS_RSP_ACK);
	assert_int_equal(fwc_wait_event(&client, FS_EVT_REPORT, &f, TIMEOUT_MS), 1);
	struct fs_report rep;
	assert_int_equal(fs_report_get(&f, &rep), 0);
	assert_int_equal(rep.result, FS_REPORT_DONE);
	assert_int_equal(rep.tick[FS_STEP_SHUT1_RISE] - rep.tick[FS_STEP_PROJ_ON], 20000);
}

static void test_sigterm_exits_and_unlinks(void **state)
{
	(void)state;
	int status = -1;
	assert_int_equal(kill(pid, SIGTERM), 0);
	assert_int_equal(waitpid(pid, &status, 0), pid);
	pid = -1;
	assert_true(WIFEXITED(status));
	assert_int_equal(WEXITSTATUS(status), 0);
	struct stat st;
	assert_int_equal(lstat(link_path, &st), -1);
	assert_int_equal(client.bad_frames, 0);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_hello_and_boot),
		cmocka_unit_test(test_fire_exact_report),
		cmocka_unit_test(test_sigusr1_presses_button),
		cmocka_unit_test(test_debug_button_when_armed),
		cmocka_unit_test(test_sigusr2_resets_mid_sequence),
		cmocka_unit_test(test_sigterm_exits_and_unlinks),
	};
	return cmocka_run_group_tests(tests, start, stop);
}
