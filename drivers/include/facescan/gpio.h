/* facescan GPIO driver: the booth button (debounced edge events), the status LED and the
 * MCU reset line.
 *
 * A driver is a const ops table (one per backend) plus an opaque handle. Backends:
 *   fscan_gpio_libgpiod_ops  real lines through libgpiod v1.6 (drivers/gpio/gpio_libgpiod.c)
 *   fscan_gpio_fake_ops      in-memory lines with test back doors (facescan/gpio_fake.h)
 *
 * Every function returns 0 or a negative errno; nothing here logs or exits.
 * The handle is not thread-safe: one thread drives it (the fake's back doors may be called
 * from another thread).
 */
#ifndef FACESCAN_GPIO_H
#define FACESCAN_GPIO_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Where the three lines are. Levels are logical: "active" means pressed / LED on / reset
 * asserted, whatever the electrical polarity (set the *_active_low flags for that). */
struct fscan_gpio_config {
	const char *chip;        /* "gpiochip0", "/dev/gpiochip0" or a label; fake: any name */
	const char *consumer;    /* label shown by gpioinfo; NULL = "facescand" */
	unsigned button_line;    /* line offset of the booth button (input, both edges) */
	bool button_active_low;  /* true when a press pulls the line low (usual with a pull-up) */
	bool button_pull_up;     /* ask for the SoC's internal pull-up (best effort) */
	unsigned led_line;       /* status LED (output, starts off) */
	bool led_active_low;
	unsigned reset_line;     /* MCU reset (output, starts deasserted) */
	bool reset_active_low;   /* true for the usual active-low nRESET */
	unsigned debounce_ms;    /* a level counts once held this long; 0 = 20 (the firmware's) */
};

enum fscan_gpio_event_type {
	FSCAN_GPIO_BUTTON_PRESSED = 1,
	FSCAN_GPIO_BUTTON_RELEASED = 2,
};

struct fscan_gpio_event {
	enum fscan_gpio_event_type type;
	uint64_t timestamp_ns; /* CLOCK_MONOTONIC of the edge (kernel timestamp for libgpiod) */
};

/* A raw, undebounced edge as a backend reports it. */
struct fscan_gpio_edge {
	bool active;           /* logical level after the edge */
	uint64_t timestamp_ns; /* CLOCK_MONOTONIC (the fake's clock for the fake) */
};

enum fscan_gpio_output {
	FSCAN_GPIO_LED = 0,
	FSCAN_GPIO_RESET = 1,
};

/* The backend interface. The debounce filter is common code above it (gpio.c), so every
 * backend only reports raw edges. */
struct fscan_gpio_ops {
	const char *name;
	/* Requests the lines. -ENODEV/-ENOENT no such chip, -EINVAL bad line, -EBUSY line in use. */
	int (*open)(const struct fscan_gpio_config *cfg, void **ret_ctx);
	void (*close)(void *ctx);
	/* Next raw edge of the button: 0, -ETIMEDOUT when none came within timeout_ms
	 * (0 = don't wait, <0 = wait forever), -EINTR, -EIO. */
	int (*read_edge)(void *ctx, int timeout_ms, struct fscan_gpio_edge *ret_edge);
	/* Current logical level of the button: 0 or 1, or -errno. */
	int (*get_button)(void *ctx);
	int (*set_output)(void *ctx, enum fscan_gpio_output which, bool active);
	/* A file descriptor that polls readable while raw edges are pending. */
	int (*fd)(void *ctx);
	/* The clock edges are stamped with (CLOCK_MONOTONIC for real lines). */
	uint64_t (*now_ns)(void *ctx);
};

extern const struct fscan_gpio_ops fscan_gpio_libgpiod_ops;
extern const struct fscan_gpio_ops fscan_gpio_fake_ops;

struct fscan_gpio;

/* Opens the lines through `ops`. On success *ret_gpio must be freed with fscan_gpio_destroy().
 * -EINVAL for NULL arguments or an incomplete config, else what ops->open returns. */
int fscan_gpio_create(const struct fscan_gpio_ops *ops, const struct fscan_gpio_config *cfg,
		      struct fscan_gpio **ret_gpio);
/* Releases the lines (LED off, reset deasserted first). Accepts NULL. */
void fscan_gpio_destroy(struct fscan_gpio *gpio);

/* Next debounced button event. Returns 0 with *ret_event filled, -ETIMEDOUT when nothing
 * happened within timeout_ms (0 = poll, <0 = forever), -EINTR, -EIO.
 * Debounce (the firmware's policy): a new level is reported once the line has held it for
 * debounce_ms, stamped when that hold completed; every edge restarts the hold, so bounces
 * delay the event and a glitch shorter than debounce_ms reports nothing. */
int fscan_gpio_read_event(struct fscan_gpio *gpio, int timeout_ms,
			  struct fscan_gpio_event *ret_event);
/* For poll()-driven loops: readable while raw edges are pending ... */
int fscan_gpio_fd(const struct fscan_gpio *gpio);
/* ... and call fscan_gpio_read_event(gpio, 0, ...) again after at most this many ms even if
 * the fd stayed quiet (a new level is being held). -1 = no deadline. */
int fscan_gpio_timeout_ms(const struct fscan_gpio *gpio);
/* True while the (debounced) button is held. */
bool fscan_gpio_button_pressed(const struct fscan_gpio *gpio);

int fscan_gpio_set_led(struct fscan_gpio *gpio, bool on);
/* Holds the MCU in reset (true) or lets it run (false). */
int fscan_gpio_set_reset(struct fscan_gpio *gpio, bool asserted);
/* Asserts reset for `ms` milliseconds (1..10000), then releases it. -EINVAL out of range. */
int fscan_gpio_pulse_reset(struct fscan_gpio *gpio, unsigned ms);

#ifdef __cplusplus
}
#endif
#endif
