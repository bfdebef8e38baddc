/* One debounce policy for the booth button, wherever it is wired: the same raw traces through
 * the firmware's sampled debouncer (firmware/core/debounce.c, 1 ms main-loop samples,
 * FW_DEBOUNCE_MS) and through the host GPIO driver's edge-driven one (drivers/gpio, its fake
 * backend, debounce_ms = FW_DEBOUNCE_MS) give the same presses at the same times. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <cmocka.h>

#include "core/debounce.h"
#include "core/fw.h"
#include "facescan/gpio.h"
#include "facescan/gpio_fake.h"

#define MS 1000000ull
#define MAX_EDGES 32
#define MAX_PRESSES 8

struct trace {
	const char *name;
	int n;
	struct {
		uint32_t t_ms;
		bool level;
	} edges[MAX_EDGES];
	uint32_t end_ms;
	int want_presses;
};

static const struct trace traces[] = {
	{"clean press", 2, {{10, true}, {110, false}}, 200, 1},
	{"bouncing press and release", 10,
	 {{10, true}, {11, false}, {12, true}, {13, false}, {14, true}, {200, false}, {201, true}, {203, false},
	  {204, true}, {206, false}},
	 300, 1},
	{"5 ms glitch", 2, {{10, true}, {15, false}}, 100, 0},
	{"just too short", 2, {{10, true}, {10 + FW_DEBOUNCE_MS - 1, false}}, 100, 0},
	{"just long enough", 2, {{10, true}, {10 + FW_DEBOUNCE_MS + 1, false}}, 100, 1},
	{"chatter, then held", 8,
	 {{10, true}, {25, false}, {40, true}, {55, false}, {70, true}, {85, false}, {100, true}, {300, false}},
	 400, 1},
	{"two presses", 4, {{10, true}, {90, false}, {150, true}, {260, false}}, 400, 2},
};

static bool level_at(const struct trace *tr, uint32_t t)
{
	bool level = false;
	for (int i = 0; i < tr->n && tr->edges[i].t_ms <= t; i++)
		level = tr->edges[i].level;
	return level;
}

/* Presses (ms) the firmware's debouncer reports, sampling every ms as its main loop does. */
static int firmware_presses(const struct trace *tr, uint32_t *ret_ms)
{
	struct fw_debounce d;
	fw_debounce_init(&d, FW_DEBOUNCE_MS, 0);
	int n = 0;
	for (uint32_t t = 0; t <= tr->end_ms; t++)
		if (fw_debounce_update(&d, level_at(tr, t), t) && n < MAX_PRESSES)
			ret_ms[n++] = t;
	return n;
}

/* Presses (ms after the trace's origin) the GPIO driver reports for the same edges. */
static int driver_presses(const struct trace *tr, uint32_t *ret_ms)
{
	const struct fscan_gpio_config cfg = {
		.chip = "fake0", .button_line = 1, .led_line = 2, .reset_line = 3, .debounce_ms = FW_DEBOUNCE_MS,
	};
	struct fscan_gpio *gpio;
	assert_int_equal(fscan_gpio_create(&fscan_gpio_fake_ops, &cfg, &gpio), 0);
	uint64_t t0 = fscan_gpio_fake_now_ns(gpio);
	for (int i = 0; i < tr->n; i++)
		assert_int_equal(fscan_gpio_fake_button_at(gpio, tr->edges[i].level, t0 + tr->edges[i].t_ms * MS), 0);
	fscan_gpio_fake_advance_ns(gpio, (uint64_t)(tr->end_ms + 1) * MS);
	int n = 0;
	struct fscan_gpio_event ev;
	while (fscan_gpio_read_event(gpio, 0, &ev) == 0)
		if (ev.type == FSCAN_GPIO_BUTTON_PRESSED && n < MAX_PRESSES)
			ret_ms[n++] = (uint32_t)((ev.timestamp_ns - t0) / MS);
	fscan_gpio_destroy(gpio);
	return n;
}

static void test_same_presses_at_the_same_times(void **state)
{
	(void)state;
	for (size_t k = 0; k < sizeof(traces) / sizeof(traces[0]); k++) {
		const struct trace *tr = &traces[k];
		uint32_t fw[MAX_PRESSES], drv[MAX_PRESSES];
		int n_fw = firmware_presses(tr, fw), n_drv = driver_presses(tr, drv);
		printf("%-28s firmware %d press(es), driver %d", tr->name, n_fw, n_drv);
		for (int i = 0; i < n_fw && i < n_drv; i++)
			printf("  [%u ms | %u ms]", fw[i], drv[i]);
		printf("\n");
		assert_int_equal(n_fw, tr->want_presses);
		assert_int_equal(n_drv, tr->want_presses);
		for (int i = 0; i < n_fw; i++)
			assert_int_equal(fw[i], drv[i]);
	}
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_same_presses_at_the_same_times),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
