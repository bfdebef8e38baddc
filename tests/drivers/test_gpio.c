/* GPIO driver through its fake backend: the debounce filter, outputs, errors. */
#include <errno.h>
#include <poll.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "facescan/gpio.h"
#include "facescan/gpio_fake.h"

#define MS 1000000ull

static const struct fscan_gpio_config cfg = {
	.chip = "fake0", .button_line = 1, .led_line = 2, .reset_line = 3, .debounce_ms = 20,
};

static int setup(void **state)
{
	struct fscan_gpio *gpio;
	assert_int_equal(fscan_gpio_create(&fscan_gpio_fake_ops, &cfg, &gpio), 0);
	*state = gpio;
	return 0;
}

static int teardown(void **state)
{
	fscan_gpio_destroy(*state);
	return 0;
}

static void test_press_reported_once_held(void **state)
{
	struct fscan_gpio *gpio = *state;
	uint64_t t0 = fscan_gpio_fake_now_ns(gpio);
	assert_int_equal(fscan_gpio_fake_button_at(gpio, true, t0), 0);
	struct fscan_gpio_event ev;
	/* Not before the line has held the level for the window... */
	assert_int_equal(fscan_gpio_read_event(gpio, 0, &ev), -ETIMEDOUT);
	int t = fscan_gpio_timeout_ms(gpio);
	assert_true(t >= 0 && t <= 20);
	/* ... then stamped when the hold completed. */
	assert_int_equal(fscan_gpio_read_event(gpio, 100, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_PRESSED);
	assert_int_equal(ev.timestamp_ns, t0 + 20 * MS);
	assert_true(fscan_gpio_button_pressed(gpio));
	assert_int_equal(fscan_gpio_timeout_ms(gpio), -1);
}

static void test_bounce_is_swallowed(void **state)
{
	struct fscan_gpio *gpio = *state;
	uint64_t t0 = fscan_gpio_fake_now_ns(gpio);
	/* A press that bounces 4 times within 4 ms and settles pressed: one press, 20 ms after
	 * the last bounce. */
	bool levels[] = {true, false, true, false, true};
	for (int i = 0; i < 5; i++)
		assert_int_equal(fscan_gpio_fake_button_at(gpio, levels[i], t0 + (uint64_t)i * MS), 0);
	struct fscan_gpio_event ev;
	assert_int_equal(fscan_gpio_read_event(gpio, 100, &ev), 0);
	assert_int_equal(ev.type, FSCAN_GPIO_BUTTON_PRESSED);
	assert_int_equal(ev.timestamp_ns, t0 + 24 * MS);
	fscan_gpio_fake_advance_ns(gpio, 30 * MS);
	/* Nothing else: the line settled where it was reported. */
	assert_int_equal(fscan_gpio_read_event(gpio, 0, &ev), -ETIMEDOUT);
	assert_int_equal(fscan_gpio_timeout_ms(gpio), -1);
}

static void test_glitch_reports_nothing(void **state)
{
	struct fscan_gpio *gpio = *state;
	uint64_t t0 = fscan_gpio_fake_now_ns(gpio);
	/* A 19 ms pulse (a spark on the cable, a brush of the button): shorter than the window. */
	fscan_gpio_fake_button_at(gpio, true, t0);
	fscan_gpio_fake_button_at(gpio, false, t0 + 19 * MS);
	fscan_gpio_fake_advance_ns(gpio, 100 * MS);
	struct fscan_gpio_event ev;
	assert_int_equal(fscan_gpio_read_event(gpio, 0, &ev), -ETIMEDOUT);
	assert_int_equal(fscan_gpio_timeout_ms(gpio), -1);
	assert_false(fscan_gpio_button_pressed(gpio));
}

static void test_events_in_order_across_late_edges(void **state)
{
	struct fscan_gpio *gpio = *state;
	uint64_t t0 = fscan_gpio_fake_now_ns(gpio);
	/* Pressed 30 ms, released 70 ms, pressed again: each level held past the window. */
	fscan_gpio_fake_button_at(gpio, true, t0);
	fscan_gpio_fake_button_at(gpio, false, t0 + 30 * MS);
	fscan_gpio_fake_button_at(gpio, true, t0 + 100 * MS);
	fscan_gpio_fake_advance_ns(gpio, 200 * MS);
	struct fscan_gpio_event ev[3];
	for (int i = 0; i < 3; i++)
		assert_int_equal(fscan_gpio_read_event(gpio, 0, &ev[i]), 0);
	assert_int_equal(ev[0].type, FSCAN_GPIO_BUTTON_PRESSED);
	assert_int_equal(ev[0].timestamp_ns, t0 + 20 * MS);
	assert_int_equal(ev[1].type, FSCAN_GPIO_BUTTON_RELEASED);
	assert_int_equal(ev[1].timestamp_ns, t0 + 50 * MS);
	assert_int_equal(ev[2].type, FSCAN_GPIO_BUTTON_PRESSED);
	assert_int_equal(ev[2].timestamp_ns, t0 + 120 * MS);
}

static void test_two_clean_presses(void **state)
{
	struct fscan_gpio *gpio = *state;
	uint64_t t0 = fscan_gpio_fake_now_ns(gpio);
	uint64_t at[] = {0, 200, 400, 600};
	for (int i = 0; i < 4; i++)
		fscan_gpio_fake_button_at(gpio, i % 2 == 0, t0 + at[i] * MS);
	fscan_gpio_fake_advance_ns(gpio, 700 * MS);
	int presses = 0, releases = 0;
	struct fscan_gpio_event ev;
	while (fscan_gpio_read_event(gpio, 0, &ev) == 0)
		ev.type == FSCAN_GPIO_BUTTON_PRESSED ? presses++ : releases++;
	assert_int_equal(presses, 2);
	assert_int_equal(releases, 2);
}

static void test_fd_polls_readable_with_pending_edges(void **state)
{
	struct fscan_gpio *gpio = *state;
	struct pollfd p = {.fd = fscan_gpio_fd(gpio), .events = POLLIN};
	assert_true(p.fd >= 0);
	assert_int_equal(poll(&p, 1, 0), 0);
	fscan_gpio_fake_button(gpio, true);
	assert_int_equal(poll(&p, 1, 0), 1);
	struct fscan_gpio_event ev;
	assert_int_equal(fscan_gpio_read_event(gpio, 100, &ev), 0);
	assert_int_equal(poll(&p, 1, 0), 0);
}

static void test_timeout_waits_then_fails(void **state)
{
	struct fscan_gpio_event ev;
	assert_int_equal(fscan_gpio_read_event(*state, 30, &ev), -ETIMEDOUT);
}

static void test_outputs(void **state)
{
	struct fscan_gpio *gpio = *state;
	assert_int_equal(fscan_gpio_fake_output(gpio, FSCAN_GPIO_LED), 0);
	assert_int_equal(fscan_gpio_set_led(gpio, true), 0);
	assert_int_equal(fscan_gpio_fake_output(gpio, FSCAN_GPIO_LED), 1);
	assert_int_equal(fscan_gpio_set_reset(gpio, true), 0);
	assert_int_equal(fscan_gpio_fake_output(gpio, FSCAN_GPIO_RESET), 1);
	assert_int_equal(fscan_gpio_set_reset(gpio, false), 0);
	assert_int_equal(fscan_gpio_pulse_reset(gpio, 2), 0);
	assert_int_equal(fscan_gpio_fake_output(gpio, FSCAN_GPIO_RESET), 0);
	assert_int_equal(fscan_gpio_fake_reset_count(gpio), 2);
	assert_int_equal(fscan_gpio_pulse_reset(gpio, 0), -EINVAL);
	assert_int_equal(fscan_gpio_pulse_reset(gpio, 10001), -EINVAL);
}

static void test_backend_errors_propagate(void **state)
{
	struct fscan_gpio *gpio = *state;
	assert_int_equal(fscan_gpio_fake_fail_next(gpio, "set_output", -EIO), 0);
	assert_int_equal(fscan_gpio_set_led(gpio, true), -EIO);
	assert_int_equal(fscan_gpio_fake_output(gpio, FSCAN_GPIO_LED), 0);
	assert_int_equal(fscan_gpio_set_led(gpio, true), 0);
	assert_int_equal(fscan_gpio_fake_fail_next(gpio, "read_edge", -EIO), 0);
	struct fscan_gpio_event ev;
	assert_int_equal(fscan_gpio_read_event(gpio, 0, &ev), -EIO);
	assert_int_equal(fscan_gpio_fake_fail_next(gpio, "nonsense", -EIO), -EINVAL);
}

static void test_create_errors(void **state)
{
	(void)state;
	struct fscan_gpio *gpio = NULL;
	struct fscan_gpio_config c = cfg;
	c.chip = FSCAN_GPIO_FAKE_MISSING_CHIP;
	assert_int_equal(fscan_gpio_create(&fscan_gpio_fake_ops, &c, &gpio), -ENODEV);
	assert_null(gpio);
	c = cfg;
	c.led_line = c.button_line;
	assert_int_equal(fscan_gpio_create(&fscan_gpio_fake_ops, &c, &gpio), -EINVAL);
	assert_int_equal(fscan_gpio_create(NULL, &cfg, &gpio), -EINVAL);
	assert_int_equal(fscan_gpio_create(&fscan_gpio_fake_ops, NULL, &gpio), -EINVAL);
	/* Back doors refuse handles of other backends. */
	assert_int_equal(fscan_gpio_fake_button(NULL, true), -EINVAL);
	fscan_gpio_destroy(NULL);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test_setup_teardown(test_press_reported_once_held, setup, teardown),
		cmocka_unit_test_setup_teardown(test_bounce_is_swallowed, setup, teardown),
		cmocka_unit_test_setup_teardown(test_glitch_reports_nothing, setup, teardown),
		cmocka_unit_test_setup_teardown(test_events_in_order_across_late_edges, setup, teardown),
		cmocka_unit_test_setup_teardown(test_two_clean_presses, setup, teardown),
		cmocka_unit_test_setup_teardown(test_fd_polls_readable_with_pending_edges, setup, teardown),
		cmocka_unit_test_setup_teardown(test_timeout_waits_then_fails, setup, teardown),
		cmocka_unit_test_setup_teardown(test_outputs, setup, teardown),
		cmocka_unit_test_setup_teardown(test_backend_errors_propagate, setup, teardown),
		cmocka_unit_test(test_create_errors),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
