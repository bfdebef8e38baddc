/* The libgpiod backend against the kernel's gpio-sim, inside the VM tier (tests/vm/README.md).
 * The contract test_gpio.c checks on the fake, on a real gpiochip: a press that bounces gives
 * exactly one debounced press (and a bouncing release one release); the LED and MCU-reset lines
 * the backend drives read back from the simulator's side with the configured polarity; a chip
 * removed while open gives a clear error, promptly; the fd facescand's loop watches instead of
 * polling (fscan_gpio_fd, the line's kernel event fd) is quiet until an edge, readable at the
 * edge, and fscan_gpio_timeout_ms() says when the held level settles. The simulator pulls the button line through
 * sysfs (sim_gpioN/pull), so the edges are real kernel edge events with kernel timestamps.
 * Outside the VM (no FACESCAN_VM=1) it skips. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "facescan/gpio.h"

#define SIM "/sys/kernel/config/gpio-sim/facescan-test"
#define BUTTON 0
#define LED 1
#define RESET 2
#define DEBOUNCE_MS 150 /* wide: under TCG on a loaded host five sysfs writes took up to 24 ms */

static char chip[64], dev[64];

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + ts.tv_nsec / 1e9;
}

static int write_file(const char *path, const char *value)
{
	int fd = open(path, O_WRONLY);
	if (fd < 0)
		return -errno;
	ssize_t n = write(fd, value, strlen(value));
	int r = n == (ssize_t)strlen(value) ? 0 : n < 0 ? -errno : -EIO;
	close(fd);
	return r;
}

static int read_file(const char *path, char *buf, size_t size)
{
	int fd = open(path, O_RDONLY);
	if (fd < 0)
		return -errno;
	ssize_t n = read(fd, buf, size - 1);
	close(fd);
	if (n < 0)
		return -errno;
	buf[n] = '\0';
	buf[strcspn(buf, "\n")] = '\0';
	return 0;
}

/* The simulator's side of line `line`: attribute "pull" or "value". */
static void sim_path(char *buf, size_t size, unsigned line, const char *attr)
{
	snprintf(buf, size, "/sys/devices/platform/%s/%s/sim_gpio%u/%s", dev, chip, line, attr);
}

static void pull(unsigned line, bool up)
{
	char p[PATH_MAX];
	sim_path(p, sizeof(p), line, "pull");
	assert_int_equal(write_file(p, up ? "pull-up" : "pull-down"), 0);
}

static int sim_value(unsigned line)
{
	char p[PATH_MAX], v[16];
	sim_path(p, sizeof(p), line, "value");
	assert_int_equal(read_file(p, v, sizeof(v)), 0);
	return atoi(v);
}

static int chip_up(void)
{
	if (mkdir(SIM, 0755) < 0 && errno != EEXIST)
		return -errno;
	if (mkdir(SIM "/bank0", 0755) < 0 && errno != EEXIST)
		return -errno;
	int r = write_file(SIM "/bank0/num_lines", "8");
	if (r == 0)
		r = write_file(SIM "/bank0/label", "facescan-booth");
	if (r == 0)
		r = write_file(SIM "/live", "1");
	if (r == 0)
		r = read_file(SIM "/bank0/chip_name", chip, sizeof(chip));
	if (r == 0)
		r = read_file(SIM "/dev_name", dev, sizeof(dev));
	return r;
}

static void chip_down(void)
{
	write_file(SIM "/live", "0");
	rmdir(SIM "/bank0");
	rmdir(SIM);
}

static const struct fscan_gpio_config booth = {
	.button_line = BUTTON, .button_active_low = true, .button_pull_up = true,
	.led_line = LED, .reset_line = RESET, .reset_active_low = true, .debounce_ms = DEBOUNCE_MS,
};

static int setup(void **state)
{
	if (chip_up() < 0)
		return -1;
	pull(BUTTON, true); /* released: the pull-up holds the line high */
	struct fscan_gpio_config cfg = booth;
	cfg.chip = chip;
	struct fscan_gpio *gpio = NULL;
	int r = fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &gpio);
	if (r < 0) {
		printf("create %s -> %d\n", chip, r);
		chip_down();
		return -1;
	}
	*state = gpio;
	return 0;
}

static int teardown(void **state)
{
	fscan_gpio_destroy(*state);
	chip_down();
	return 0;
}

/* Bounces: `n` level changes ending at `final`, as fast as sysfs takes them (well inside the
 * debounce window: measured and asserted). */
static void bounce(unsigned line, bool final, int n)
{
	double t0 = now_s();
	for (int i = 0; i < n; i++)
		pull(line, (n - 1 - i) % 2 == 0 ? final : !final);
	double dt = now_s() - t0;
	printf("%d edges in %.2f ms\n", n, dt * 1e3);
	assert_true(dt * 1e3 < DEBOUNCE_MS);
}

static void test_bouncing_press_is_one_press(void **state)
{
	struct fscan_gpio *gpio = *state;
	struct fscan_gpio_event ev;
	assert_int_equal(fscan_gpio_read_event(gpio, 0, &ev), -ETIMEDOUT);
	assert_false(fscan_gpio_button_pressed(gpio));
	/* Press: active low, so pulled down; 5 edges ending pressed. */
	bounce(BUTTON, false, 5);
	assert_int_equal(fscan_gpio_read_event(gpio, 1000, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_PRESSED);
	assert_true(fscan_gpio_button_pressed(gpio));
	/* The rest was bounce: nothing more within and after the window. */
	assert_int_equal(fscan_gpio_read_event(gpio, 3 * DEBOUNCE_MS, &ev), -ETIMEDOUT);
	/* Release, bouncing too: exactly one release. */
	bounce(BUTTON, true, 5);
	assert_int_equal(fscan_gpio_read_event(gpio, 1000, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_RELEASED);
	assert_int_equal(fscan_gpio_read_event(gpio, 3 * DEBOUNCE_MS, &ev), -ETIMEDOUT);
	assert_false(fscan_gpio_button_pressed(gpio));
}

static void test_tap_shorter_than_window_is_ignored(void **state)
{
	/* Press and release within the window (a glitch, a brush of the button): the level was
	 * never held for the window, so nothing is reported (the firmware's policy). */
	struct fscan_gpio *gpio = *state;
	struct fscan_gpio_event ev;
	double t0 = now_s();
	pull(BUTTON, false);
	pull(BUTTON, true);
	double tap_ms = (now_s() - t0) * 1e3;
	printf("tap of %.1f ms (window %d ms)\n", tap_ms, DEBOUNCE_MS);
	assert_true(tap_ms < DEBOUNCE_MS);
	assert_int_equal(fscan_gpio_read_event(gpio, 3 * DEBOUNCE_MS, &ev), -ETIMEDOUT);
	assert_false(fscan_gpio_button_pressed(gpio));
	/* A press held past the window after it is reported as usual. */
	pull(BUTTON, false);
	assert_int_equal(fscan_gpio_read_event(gpio, 1000, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_PRESSED);
	pull(BUTTON, true);
	assert_int_equal(fscan_gpio_read_event(gpio, 1000, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_RELEASED);
}

/* What GpioMcu relies on (tests/daemon/test_daemon.cpp checks the same on the fake): the fd is
 * quiet with no edge, readable once the line moves, quiet again when the edge is read; the held
 * level then settles within fscan_gpio_timeout_ms() without another wake-up. */
static bool fd_readable(struct fscan_gpio *gpio, int timeout_ms)
{
	struct pollfd p = {.fd = fscan_gpio_fd(gpio), .events = POLLIN};
	assert_true(p.fd >= 0);
	return poll(&p, 1, timeout_ms) > 0;
}

static void test_fd_wakes_on_an_edge(void **state)
{
	struct fscan_gpio *gpio = *state;
	struct fscan_gpio_event ev;
	assert_false(fd_readable(gpio, 0));
	assert_int_equal(fscan_gpio_timeout_ms(gpio), -1);
	double t0 = now_s();
	pull(BUTTON, false); /* press (active low) */
	assert_true(fd_readable(gpio, 1000));
	printf("fd readable %.2f ms after the pull\n", (now_s() - t0) * 1e3);
	/* The edge is read; the level is not held long enough yet. */
	assert_int_equal(fscan_gpio_read_event(gpio, 0, &ev), -ETIMEDOUT);
	assert_false(fd_readable(gpio, 0));
	int due = fscan_gpio_timeout_ms(gpio);
	printf("settles in %d ms\n", due);
	assert_true(due >= 0 && due <= DEBOUNCE_MS);
	/* Nothing else wakes the loop: it sleeps the deadline, then the press is there. */
	assert_false(fd_readable(gpio, due + 5));
	assert_int_equal(fscan_gpio_read_event(gpio, 0, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_PRESSED);
	assert_int_equal(fscan_gpio_timeout_ms(gpio), -1);
	pull(BUTTON, true);
	assert_true(fd_readable(gpio, 1000));
}

static void test_outputs_read_back_on_the_sim_side(void **state)
{
	struct fscan_gpio *gpio = *state;
	/* After open: LED off, reset deasserted (active low: high). */
	assert_int_equal(sim_value(LED), 0);
	assert_int_equal(sim_value(RESET), 1);
	assert_int_equal(fscan_gpio_set_led(gpio, true), 0);
	assert_int_equal(sim_value(LED), 1);
	assert_int_equal(fscan_gpio_set_reset(gpio, true), 0);
	assert_int_equal(sim_value(RESET), 0);
	assert_int_equal(fscan_gpio_set_reset(gpio, false), 0);
	assert_int_equal(sim_value(RESET), 1);
	assert_int_equal(fscan_gpio_pulse_reset(gpio, 5), 0);
	assert_int_equal(sim_value(RESET), 1);
	assert_int_equal(fscan_gpio_set_led(gpio, false), 0);
	assert_int_equal(sim_value(LED), 0);
}

static void test_lines_in_use_are_busy(void **state)
{
	(void)state;
	struct fscan_gpio_config cfg = booth;
	cfg.chip = chip;
	struct fscan_gpio *second = NULL;
	assert_int_equal(fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &second), -EBUSY);
	assert_null(second);
	cfg.chip = "gpiochip-facescan-absent";
	int r = fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &second);
	assert_true(r == -ENOENT || r == -ENODEV);
	cfg.chip = chip;
	cfg.button_line = 8; /* the chip has 8 lines */
	assert_int_equal(fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &second), -EINVAL);
}

static void test_chip_removed_while_open(void **state)
{
	struct fscan_gpio *gpio = *state;
	assert_int_equal(write_file(SIM "/live", "0"), 0);
	struct fscan_gpio_event ev;
	double t0 = now_s();
	int r = fscan_gpio_read_event(gpio, 2000, &ev);
	double dt = now_s() - t0;
	printf("read_event after removal -> %d (%s) in %.3f s\n", r, strerror(-r), dt);
	assert_int_equal(r, -ENODEV);
	assert_true(dt < 1.0);
	r = fscan_gpio_set_led(gpio, true);
	printf("set_led after removal -> %d (%s)\n", r, strerror(-r));
	assert_int_equal(r, -ENODEV);
}

int main(void)
{
	if (!getenv("FACESCAN_VM")) {
		fprintf(stderr, "test_vm_gpio: skipped: runs inside the VM tier (tests/vm/test_vm.sh), where "
				"gpio-sim provides the chip\n");
		return 77;
	}
	alarm(60);
	const struct CMUnitTest tests[] = {
		cmocka_unit_test_setup_teardown(test_bouncing_press_is_one_press, setup, teardown),
		cmocka_unit_test_setup_teardown(test_tap_shorter_than_window_is_ignored, setup, teardown),
		cmocka_unit_test_setup_teardown(test_fd_wakes_on_an_edge, setup, teardown),
		cmocka_unit_test_setup_teardown(test_outputs_read_back_on_the_sim_side, setup, teardown),
		cmocka_unit_test_setup_teardown(test_lines_in_use_are_busy, setup, teardown),
		cmocka_unit_test_setup_teardown(test_chip_removed_while_open, setup, teardown),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
