/* The libgpiod backend against mocks of libgpiod v1 (-Wl,--wrap, see the .ldflags): which lines
 * it requests with which flags, how it turns kernel edge events into logical edges, and how
 * libgpiod's errors come back as -errno. The build host has no gpiochip, so this is where the
 * backend's logic is tested; test_gpio_libgpiod_real checks the real library's failure path. */
#include <errno.h>
#include <gpiod.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "facescan/gpio.h"

/* Stand-ins for libgpiod's opaque objects: only their addresses are used. */
static char chip_obj;
static char line_obj[3];
static int event_pipe[2];

struct gpiod_chip *__wrap_gpiod_chip_open_lookup(const char *descr)
{
	check_expected(descr);
	struct gpiod_chip *chip = mock_ptr_type(struct gpiod_chip *);
	if (!chip)
		errno = ENOENT;
	return chip;
}

struct gpiod_line *__wrap_gpiod_chip_get_line(struct gpiod_chip *chip, unsigned int offset)
{
	assert_ptr_equal(chip, &chip_obj);
	if (offset > 2) {
		errno = EINVAL;
		return NULL;
	}
	return (struct gpiod_line *)&line_obj[offset];
}

void __wrap_gpiod_chip_close(struct gpiod_chip *chip)
{
	assert_ptr_equal(chip, &chip_obj);
	function_called();
}

int __wrap_gpiod_line_request_both_edges_events_flags(struct gpiod_line *line, const char *consumer, int flags)
{
	check_expected_ptr(line);
	check_expected(consumer);
	check_expected(flags);
	int r = mock_type(int);
	if (r < 0)
		errno = -r;
	return r < 0 ? -1 : 0;
}

int __wrap_gpiod_line_request_output_flags(struct gpiod_line *line, const char *consumer, int flags, int default_val)
{
	check_expected_ptr(line);
	(void)consumer;
	check_expected(flags);
	assert_int_equal(default_val, 0); /* LED off, reset released */
	return 0;
}

int __wrap_gpiod_line_event_get_fd(struct gpiod_line *line)
{
	assert_ptr_equal(line, &line_obj[0]);
	return event_pipe[0];
}

int __wrap_gpiod_line_event_read(struct gpiod_line *line, struct gpiod_line_event *event)
{
	assert_ptr_equal(line, &line_obj[0]);
	char c;
	assert_int_equal(read(event_pipe[0], &c, 1), 1);
	event->event_type = c == 'r' ? GPIOD_LINE_EVENT_RISING_EDGE : GPIOD_LINE_EVENT_FALLING_EDGE;
	event->ts.tv_sec = mock_type(long);
	event->ts.tv_nsec = 0;
	return 0;
}

int __wrap_gpiod_line_get_value(struct gpiod_line *line)
{
	assert_ptr_equal(line, &line_obj[0]);
	return mock_type(int);
}

int __wrap_gpiod_line_set_value(struct gpiod_line *line, int value)
{
	check_expected_ptr(line);
	check_expected(value);
	return 0;
}

static const struct fscan_gpio_config cfg = {
	.chip = "gpiochip0", .button_line = 0, .button_active_low = true, .button_pull_up = true,
	.led_line = 1, .reset_line = 2, .reset_active_low = true, .debounce_ms = 10,
};

static void expect_open(int button_request_result)
{
	expect_string(__wrap_gpiod_chip_open_lookup, descr, "gpiochip0");
	will_return(__wrap_gpiod_chip_open_lookup, &chip_obj);
	expect_value(__wrap_gpiod_line_request_both_edges_events_flags, line, &line_obj[0]);
	expect_string(__wrap_gpiod_line_request_both_edges_events_flags, consumer, "facescand");
	expect_value(__wrap_gpiod_line_request_both_edges_events_flags, flags,
		     GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW | GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP);
	will_return(__wrap_gpiod_line_request_both_edges_events_flags, button_request_result);
	if (button_request_result < 0)
		return;
	expect_value(__wrap_gpiod_line_request_output_flags, line, &line_obj[1]);
	expect_value(__wrap_gpiod_line_request_output_flags, flags, 0);
	expect_value(__wrap_gpiod_line_request_output_flags, line, &line_obj[2]);
	expect_value(__wrap_gpiod_line_request_output_flags, flags, GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW);
	will_return(__wrap_gpiod_line_get_value, 0); /* button released at start */
}

static void expect_destroy(void)
{
	expect_value(__wrap_gpiod_line_set_value, line, &line_obj[1]);
	expect_value(__wrap_gpiod_line_set_value, value, 0);
	expect_value(__wrap_gpiod_line_set_value, line, &line_obj[2]);
	expect_value(__wrap_gpiod_line_set_value, value, 0);
	expect_function_call(__wrap_gpiod_chip_close);
}

static int setup(void **state)
{
	(void)state;
	return pipe(event_pipe);
}

static int teardown(void **state)
{
	(void)state;
	close(event_pipe[0]);
	close(event_pipe[1]);
	return 0;
}

static void test_requests_lines_with_flags(void **state)
{
	(void)state;
	struct fscan_gpio *gpio;
	expect_open(0);
	assert_int_equal(fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &gpio), 0);
	assert_int_equal(fscan_gpio_fd(gpio), event_pipe[0]);
	expect_value(__wrap_gpiod_line_set_value, line, &line_obj[1]);
	expect_value(__wrap_gpiod_line_set_value, value, 1);
	assert_int_equal(fscan_gpio_set_led(gpio, true), 0);
	expect_value(__wrap_gpiod_line_set_value, line, &line_obj[2]);
	expect_value(__wrap_gpiod_line_set_value, value, 1);
	assert_int_equal(fscan_gpio_set_reset(gpio, true), 0);
	expect_destroy();
	fscan_gpio_destroy(gpio);
}

static void test_kernel_edges_become_events(void **state)
{
	(void)state;
	struct fscan_gpio *gpio;
	expect_open(0);
	assert_int_equal(fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &gpio), 0);
	/* With ACTIVE_LOW requested, the kernel reports a press as a rising edge. */
	assert_int_equal(write(event_pipe[1], "rf", 2), 2);
	will_return(__wrap_gpiod_line_event_read, 100L);
	will_return(__wrap_gpiod_line_event_read, 101L);
	struct fscan_gpio_event ev;
	assert_int_equal(fscan_gpio_read_event(gpio, 100, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_PRESSED);
	/* Stamped when the level had been held for the window (debounce_ms = 10). */
	assert_int_equal(ev.timestamp_ns, 100ull * 1000000000ull + 10ull * 1000000ull);
	assert_int_equal(fscan_gpio_read_event(gpio, 100, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_RELEASED);
	assert_int_equal(ev.timestamp_ns, 101ull * 1000000000ull + 10ull * 1000000ull);
	assert_int_equal(fscan_gpio_read_event(gpio, 10, &ev), -ETIMEDOUT);
	expect_destroy();
	fscan_gpio_destroy(gpio);
}

static void test_missing_chip(void **state)
{
	(void)state;
	struct fscan_gpio *gpio = NULL;
	expect_string(__wrap_gpiod_chip_open_lookup, descr, "gpiochip0");
	will_return(__wrap_gpiod_chip_open_lookup, NULL);
	assert_int_equal(fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &gpio), -ENOENT);
	assert_null(gpio);
}

static void test_busy_line_closes_chip(void **state)
{
	(void)state;
	struct fscan_gpio *gpio = NULL;
	expect_open(-EBUSY);
	expect_function_call(__wrap_gpiod_chip_close);
	assert_int_equal(fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &gpio), -EBUSY);
	assert_null(gpio);
}

static void test_bad_line_offset(void **state)
{
	(void)state;
	struct fscan_gpio *gpio = NULL;
	struct fscan_gpio_config c = cfg;
	c.button_line = 7;
	expect_string(__wrap_gpiod_chip_open_lookup, descr, "gpiochip0");
	will_return(__wrap_gpiod_chip_open_lookup, &chip_obj);
	expect_function_call(__wrap_gpiod_chip_close);
	assert_int_equal(fscan_gpio_create(&fscan_gpio_libgpiod_ops, &c, &gpio), -EINVAL);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test_setup_teardown(test_requests_lines_with_flags, setup, teardown),
		cmocka_unit_test_setup_teardown(test_kernel_edges_become_events, setup, teardown),
		cmocka_unit_test_setup_teardown(test_missing_chip, setup, teardown),
		cmocka_unit_test_setup_teardown(test_busy_line_closes_chip, setup, teardown),
		cmocka_unit_test_setup_teardown(test_bad_line_offset, setup, teardown),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
