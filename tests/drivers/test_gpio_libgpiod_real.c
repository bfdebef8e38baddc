/* The libgpiod backend on the real library: without a GPIO chip (the build host has none) it
 * must fail cleanly with -ENOENT/-ENODEV; with chips present it opens one by the lines the
 * environment names (FACESCAN_GPIO_CHIP, _BUTTON, _LED, _RESET), else it skips (77). */
#include <errno.h>
#include <glob.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "facescan/gpio.h"

static size_t chips(void)
{
	glob_t g;
	size_t n = 0;
	if (glob("/dev/gpiochip*", 0, NULL, &g) == 0)
		n = g.gl_pathc;
	globfree(&g);
	return n;
}

static void test_missing_chip_fails_cleanly(void **state)
{
	(void)state;
	struct fscan_gpio_config cfg = {.chip = "gpiochip-facescan-absent", .button_line = 0, .led_line = 1, .reset_line = 2};
	struct fscan_gpio *gpio = NULL;
	int r = fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &gpio);
	assert_true(r == -ENOENT || r == -ENODEV);
	assert_null(gpio);
}

static void test_configured_lines(void **state)
{
	(void)state;
	const char *chip = getenv("FACESCAN_GPIO_CHIP");
	if (!chip || chips() == 0) {
		skip();
		return;
	}
	struct fscan_gpio_config cfg = {
		.chip = chip,
		.button_line = (unsigned)atoi(getenv("FACESCAN_GPIO_BUTTON") ? getenv("FACESCAN_GPIO_BUTTON") : "0"),
		.led_line = (unsigned)atoi(getenv("FACESCAN_GPIO_LED") ? getenv("FACESCAN_GPIO_LED") : "1"),
		.reset_line = (unsigned)atoi(getenv("FACESCAN_GPIO_RESET") ? getenv("FACESCAN_GPIO_RESET") : "2"),
	};
	struct fscan_gpio *gpio = NULL;
	assert_int_equal(fscan_gpio_create(&fscan_gpio_libgpiod_ops, &cfg, &gpio), 0);
	assert_int_equal(fscan_gpio_set_led(gpio, true), 0);
	assert_int_equal(fscan_gpio_pulse_reset(gpio, 5), 0);
	fscan_gpio_destroy(gpio);
}

int main(void)
{
	printf("%zu gpiochip device(s)\n", chips());
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_missing_chip_fails_cleanly),
		cmocka_unit_test(test_configured_lines),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
