/*
 * facescan-fw-native: the firmware core on the native board, behind a pseudo-terminal, for
 * the daemon and demos on machines without QEMU. The virtual 1 MHz clock follows the host's
 * monotonic clock; sequence steps land on their exact virtual ticks.
 *
 *   facescan-fw-native [--link PATH] [--trace]
 *
 * Prints the pty path on stdout (and symlinks PATH to it). SIGUSR1 presses the booth button
 * for 100 ms; SIGUSR2 pulls the reset pin (lines low, the core starts again and sends
 * EVT_BOOT, reset cause pin), as a brown-out or a reset mid-sequence would. FS_CMD_DEBUG_BUTTON
 * is accepted (this is a simulated board). SIGINT/SIGTERM end it.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "boards/native/native.h"
#include "core/fw.h"
#include "protocol/protocol.h"

static volatile sig_atomic_t stop_requested;
static volatile sig_atomic_t button_requests;
static volatile sig_atomic_t reset_requests;

static void on_stop(int sig)
{
	(void)sig;
	stop_requested = 1;
}

static void on_button(int sig)
{
	(void)sig;
	button_requests++;
}

static void on_reset(int sig)
{
	(void)sig;
	reset_requests++;
}

static uint64_t mono_us(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static void to_master(const uint8_t *buf, size_t len, void *ctx)
{
	int fd = *(int *)ctx;
	while (len > 0) {
		ssize_t w = write(fd, buf, len);
		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0)
			return; /* nobody reading and the pty buffer is full: the bytes are lost */
		buf += w;
		len -= (size_t)w;
	}
}

static int usage(FILE *out, int code)
{
	fprintf(out, "usage: facescan-fw-native [--link PATH] [--trace]\n"
		     "Runs the trigger firmware on a simulated board behind a pseudo-terminal.\n"
		     "  --link PATH  also make PATH a symlink to the pty\n"
		     "  --trace      print every line change to stderr\n"
		     "SIGUSR1 presses the booth button; SIGUSR2 resets the MCU (reset pin).\n");
	return code;
}

int main(int argc, char **argv)
{
	const char *link_path = NULL;
	int trace = 0;
	for (int i = 1; i < argc; i++) {
		if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h"))
			return usage(stdout, 0);
		if (!strcmp(argv[i], "--trace")) {
			trace = 1;
		} else if (!strcmp(argv[i], "--link") && i + 1 < argc) {
			link_path = argv[++i];
		} else {
			fprintf(stderr, "facescan-fw-native: bad argument '%s'\n", argv[i]);
			return usage(stderr, 2);
		}
	}

	int master = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK);
	if (master < 0 || grantpt(master) < 0 || unlockpt(master) < 0) {
		perror("facescan-fw-native: pty");
		return 1;
	}
	const char *slave_name = ptsname(master);
	/* Hold the slave open in raw mode: no echo or line editing before a client configures
	 * it, and no hang-up when a client closes. */
	int slave = slave_name ? open(slave_name, O_RDWR | O_NOCTTY) : -1;
	struct termios tio;
	if (slave < 0 || tcgetattr(slave, &tio) < 0) {
		perror("facescan-fw-native: pty slave");
		return 1;
	}
	cfmakeraw(&tio);
	tcsetattr(slave, TCSANOW, &tio);
	if (link_path) {
		unlink(link_path);
		if (symlink(slave_name, link_path) < 0) {
			perror("facescan-fw-native: symlink");
			return 1;
		}
	}
	printf("%s\n", slave_name);
	fflush(stdout);

	struct sigaction sa;
	memset(&sa, 0, sizeof(sa));
	sa.sa_handler = on_stop;
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGTERM, &sa, NULL);
	sa.sa_handler = on_button;
	sigaction(SIGUSR1, &sa, NULL);
	sa.sa_handler = on_reset;
	sigaction(SIGUSR2, &sa, NULL);

	native_set_uart_sink(to_master, &master);
	native_set_debug_inputs(true);
	native_reset(FS_RESET_POWER);
	fw_core_init();

	uint64_t start = mono_us();
	uint64_t button_until = 0;
	size_t edges_seen = 0;
	while (!stop_requested) {
		uint64_t due = native_next_due();
		int timeout_ms = due < 1000u ? 0 : 1;
		struct pollfd pfd = { .fd = master, .events = POLLIN };
		if (poll(&pfd, 1, timeout_ms) > 0 && (pfd.revents & POLLIN)) {
			uint8_t buf[256];
			ssize_t n = read(master, buf, sizeof(buf));
			if (n > 0)
				native_uart_inject(buf, (size_t)n);
		}
		uint64_t now = mono_us() - start;
		if (now > native_now())
			native_advance(now - native_now());
		if (reset_requests) {
			reset_requests = 0;
			button_until = 0;
			native_reset(FS_RESET_PIN);
			fw_core_init();
			edges_seen = 0;
		}
		if (button_requests) {
			button_requests = 0;
			button_until = native_now() + 100000u;
		}
		native_set_button(native_now() < button_until);
		fw_core_poll();

		const struct native_edge *e;
		size_t n = native_edges(&e);
		if (trace)
			for (size_t i = edges_seen; i < n; i++)
				fprintf(stderr, "tick %llu lines 0x%02x -> 0x%02x\n",
					(unsigned long long)e[i].tick, e[i].before, e[i].after);
		edges_seen = n;
		if (n == NATIVE_EDGE_LOG) {
			native_clear_edges();
			edges_seen = 0;
		}
	}
	if (link_path)
		unlink(link_path);
	close(slave);
	close(master);
	return 0;
}
