/* Back doors of the fake GPIO backend (fscan_gpio_fake_ops), in the spirit of Zephyr's
 * gpio_emul.h: tests press the button and read the outputs. Every function takes a handle that
 * was created with fscan_gpio_fake_ops and returns -EINVAL for any other handle.
 * These may be called from another thread than the one reading events.
 *
 * The fake's clock is CLOCK_MONOTONIC plus an offset that fscan_gpio_fake_advance_ns() moves
 * forward, so a test can walk through debounce windows without sleeping.
 */
#ifndef FACESCAN_GPIO_FAKE_H
#define FACESCAN_GPIO_FAKE_H

#include "facescan/gpio.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Queues a raw button edge to logical level `active`, stamped with the fake's clock now. */
int fscan_gpio_fake_button(struct fscan_gpio *gpio, bool active);
/* Same with an explicit timestamp (on the fake's clock) — for bounce trains. */
int fscan_gpio_fake_button_at(struct fscan_gpio *gpio, bool active, uint64_t timestamp_ns);
/* Moves the fake's clock forward. */
int fscan_gpio_fake_advance_ns(struct fscan_gpio *gpio, uint64_t ns);
/* The fake's clock now (what backend ops->now_ns returns). */
uint64_t fscan_gpio_fake_now_ns(struct fscan_gpio *gpio);
/* Logical level of an output line: 0 or 1, or -EINVAL. */
int fscan_gpio_fake_output(struct fscan_gpio *gpio, enum fscan_gpio_output which);
/* How many times the reset line went from asserted to released (completed reset pulses). */
int fscan_gpio_fake_reset_count(struct fscan_gpio *gpio);
/* Makes the next call of backend op `op` ("read_edge", "get_button", "set_output") fail with
 * `err` (a negative errno) once. */
int fscan_gpio_fake_fail_next(struct fscan_gpio *gpio, const char *op, int err);

/* fscan_gpio_fake_ops->open fails with -ENODEV when cfg->chip is this name: lets a test see
 * how a caller handles a missing chip. */
#define FSCAN_GPIO_FAKE_MISSING_CHIP "missing"

#ifdef __cplusplus
}
#endif
#endif
