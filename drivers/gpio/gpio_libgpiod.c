/* Real GPIO backend on libgpiod v1.6 (Debian 12). The button is requested for both-edge
 * events with the ACTIVE_LOW flag where configured, so the kernel already reports logical
 * levels and RISING means "became active". */
#include "gpio_internal.h"

#include <errno.h>
#include <gpiod.h>
#include <poll.h>
#include <stdlib.h>
#include <time.h>

struct lines {
	struct gpiod_chip *chip;
	struct gpiod_line *button, *led, *reset;
};

static int errno_or(int fallback)
{
	return errno > 0 ? -errno : fallback;
}

static int request_output(struct gpiod_chip *chip, unsigned offset, bool active_low,
			  const char *consumer, struct gpiod_line **ret_line)
{
	struct gpiod_line *line = gpiod_chip_get_line(chip, offset);
	if (!line)
		return errno_or(-EINVAL);
	int flags = active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
	if (gpiod_line_request_output_flags(line, consumer, flags, 0) < 0)
		return errno_or(-EIO);
	*ret_line = line;
	return 0;
}

static int lg_open(const struct fscan_gpio_config *cfg, void **ret_ctx)
{
	const char *consumer = cfg->consumer ? cfg->consumer : "facescand";
	struct lines *l = calloc(1, sizeof(*l));
	if (!l)
		return -ENOMEM;
	int r;
	errno = 0;
	l->chip = gpiod_chip_open_lookup(cfg->chip);
	if (!l->chip) {
		r = errno_or(-ENODEV);
		goto err_free;
	}
	l->button = gpiod_chip_get_line(l->chip, cfg->button_line);
	if (!l->button) {
		r = errno_or(-EINVAL);
		goto err_close_chip;
	}
	int flags = 0;
	if (cfg->button_active_low)
		flags |= GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW;
	if (cfg->button_pull_up)
		flags |= GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP;
	if (gpiod_line_request_both_edges_events_flags(l->button, consumer, flags) < 0) {
		r = errno_or(-EIO);
		goto err_close_chip;
	}
	r = request_output(l->chip, cfg->led_line, cfg->led_active_low, consumer, &l->led);
	if (r < 0)
		goto err_close_chip;
	r = request_output(l->chip, cfg->reset_line, cfg->reset_active_low, consumer, &l->reset);
	if (r < 0)
		goto err_close_chip;
	*ret_ctx = l;
	return 0;

err_close_chip:
	gpiod_chip_close(l->chip); /* releases every line requested from it */
err_free:
	free(l);
	return r;
}

static void lg_close(void *ctx)
{
	struct lines *l = ctx;
	gpiod_chip_close(l->chip);
	free(l);
}

static int lg_read_edge(void *ctx, int timeout_ms, struct fscan_gpio_edge *ret_edge)
{
	struct lines *l = ctx;
	struct pollfd p = {.fd = gpiod_line_event_get_fd(l->button), .events = POLLIN | POLLPRI};
	if (p.fd < 0)
		return -EIO;
	int n = poll(&p, 1, timeout_ms);
	if (n < 0)
		return -errno;
	if (n == 0)
		return -ETIMEDOUT;
	struct gpiod_line_event ev;
	if (gpiod_line_event_read(l->button, &ev) < 0)
		return errno_or(-EIO);
	ret_edge->active = ev.event_type == GPIOD_LINE_EVENT_RISING_EDGE;
	ret_edge->timestamp_ns = (uint64_t)ev.ts.tv_sec * 1000000000u + (uint64_t)ev.ts.tv_nsec;
	return 0;
}

static int lg_get_button(void *ctx)
{
	struct lines *l = ctx;
	int v = gpiod_line_get_value(l->button);
	return v < 0 ? errno_or(-EIO) : v;
}

static int lg_set_output(void *ctx, enum fscan_gpio_output which, bool active)
{
	struct lines *l = ctx;
	struct gpiod_line *line = which == FSCAN_GPIO_LED ? l->led : which == FSCAN_GPIO_RESET ? l->reset : NULL;
	if (!line)
		return -EINVAL;
	return gpiod_line_set_value(line, active) < 0 ? errno_or(-EIO) : 0;
}

static int lg_fd(void *ctx)
{
	struct lines *l = ctx;
	int fd = gpiod_line_event_get_fd(l->button);
	return fd < 0 ? -EIO : fd;
}

static uint64_t lg_now(void *ctx)
{
	(void)ctx;
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

const struct fscan_gpio_ops fscan_gpio_libgpiod_ops = {
	.name = "libgpiod",
	.open = lg_open,
	.close = lg_close,
	.read_edge = lg_read_edge,
	.get_button = lg_get_button,
	.set_output = lg_set_output,
	.fd = lg_fd,
	.now_ns = lg_now,
};
