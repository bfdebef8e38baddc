/* Common part of the GPIO driver: argument checks and the debounce filter over a backend's
 * raw edges. Time comes only from edge timestamps and the backend's clock, so the fake makes
 * it deterministic. */
#include "gpio_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <time.h>

#define DEFAULT_DEBOUNCE_MS 20u

int fscan_gpio_create(const struct fscan_gpio_ops *ops, const struct fscan_gpio_config *cfg,
		      struct fscan_gpio **ret_gpio)
{
	if (!ops || !cfg || !ret_gpio || !cfg->chip || !ops->open)
		return -EINVAL;
	if (cfg->button_line == cfg->led_line || cfg->button_line == cfg->reset_line ||
	    cfg->led_line == cfg->reset_line)
		return -EINVAL;
	struct fscan_gpio *gpio = calloc(1, sizeof(*gpio));
	if (!gpio)
		return -ENOMEM;
	gpio->ops = ops;
	gpio->debounce_ns = (uint64_t)(cfg->debounce_ms ? cfg->debounce_ms : DEFAULT_DEBOUNCE_MS) * 1000000u;
	int r = ops->open(cfg, &gpio->ctx);
	if (r < 0)
		goto err_free;
	r = ops->get_button(gpio->ctx);
	if (r < 0)
		goto err_close;
	gpio->reported = r;
	gpio->raw = r;
	*ret_gpio = gpio;
	return 0;

err_close:
	ops->close(gpio->ctx);
err_free:
	free(gpio);
	return r;
}

void fscan_gpio_destroy(struct fscan_gpio *gpio)
{
	if (!gpio)
		return;
	gpio->ops->set_output(gpio->ctx, FSCAN_GPIO_LED, false);
	gpio->ops->set_output(gpio->ctx, FSCAN_GPIO_RESET, false);
	gpio->ops->close(gpio->ctx);
	free(gpio);
}

static void report(struct fscan_gpio *gpio, bool active, uint64_t t, struct fscan_gpio_event *ev)
{
	gpio->reported = active;
	gpio->window_open = true;
	gpio->window_end = t + gpio->debounce_ns;
	ev->type = active ? FSCAN_GPIO_BUTTON_PRESSED : FSCAN_GPIO_BUTTON_RELEASED;
	ev->timestamp_ns = t;
}

/* Closes an expired window; returns true with *ev filled if the line settled on the other
 * level during it. */
static bool settle(struct fscan_gpio *gpio, uint64_t now, struct fscan_gpio_event *ev)
{
	if (!gpio->window_open || now < gpio->window_end)
		return false;
	gpio->window_open = false;
	if (gpio->raw == gpio->reported)
		return false;
	report(gpio, gpio->raw, gpio->window_end, ev);
	return true;
}

/* Feeds one raw edge; returns true with *ev filled if it is a reportable change. */
static bool feed(struct fscan_gpio *gpio, const struct fscan_gpio_edge *edge, struct fscan_gpio_event *ev)
{
	gpio->raw = edge->active;
	if (gpio->window_open && edge->timestamp_ns < gpio->window_end)
		return false; /* bounce */
	gpio->window_open = false;
	if (edge->active == gpio->reported)
		return false;
	report(gpio, edge->active, edge->timestamp_ns, ev);
	return true;
}

static int64_t ms_until(uint64_t now, uint64_t end)
{
	if (end <= now)
		return 0;
	return (int64_t)((end - now + 999999u) / 1000000u);
}

static uint64_t mono_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

static bool expired(int timeout_ms, uint64_t start)
{
	return timeout_ms >= 0 && mono_ms() - start >= (uint64_t)timeout_ms;
}

int fscan_gpio_read_event(struct fscan_gpio *gpio, int timeout_ms, struct fscan_gpio_event *ret_event)
{
	if (!gpio || !ret_event)
		return -EINVAL;
	struct fscan_gpio_event ev;
	uint64_t start = mono_ms();
	for (;;) {
		struct fscan_gpio_edge edge;
		int r;
		if (gpio->has_pending_edge) {
			edge = gpio->pending_edge;
			gpio->has_pending_edge = false;
			r = 0;
		} else {
			/* Edges already queued come before any judgement by the clock. */
			r = gpio->ops->read_edge(gpio->ctx, 0, &edge);
		}
		if (r == -ETIMEDOUT) {
			if (settle(gpio, gpio->ops->now_ns(gpio->ctx), &ev))
				break;
			if (expired(timeout_ms, start))
				return -ETIMEDOUT;
			/* Wait for the next raw edge, but not past the end of a window that may
			 * settle on a change. */
			int wait = timeout_ms;
			if (timeout_ms > 0) {
				uint64_t spent = mono_ms() - start;
				wait = spent >= (uint64_t)timeout_ms ? 0 : (int)(timeout_ms - spent);
			}
			if (gpio->window_open && gpio->raw != gpio->reported) {
				int64_t w = ms_until(gpio->ops->now_ns(gpio->ctx), gpio->window_end);
				if (wait < 0 || w < wait)
					wait = (int)w;
			}
			r = gpio->ops->read_edge(gpio->ctx, wait, &edge);
			if (r == -ETIMEDOUT)
				continue;
		}
		if (r < 0)
			return r;
		/* An edge after an expired window: the window settles first (at its own end),
		 * then the edge is fed on the next round. */
		if (gpio->window_open && edge.timestamp_ns >= gpio->window_end &&
		    settle(gpio, edge.timestamp_ns, &ev)) {
			gpio->pending_edge = edge;
			gpio->has_pending_edge = true;
			break;
		}
		if (feed(gpio, &edge, &ev))
			break;
	}
	*ret_event = ev;
	return 0;
}

int fscan_gpio_fd(const struct fscan_gpio *gpio)
{
	if (!gpio)
		return -EINVAL;
	return gpio->ops->fd(gpio->ctx);
}

int fscan_gpio_timeout_ms(const struct fscan_gpio *gpio)
{
	if (!gpio)
		return -1;
	if (gpio->has_pending_edge)
		return 0;
	if (!gpio->window_open || gpio->raw == gpio->reported)
		return -1;
	int64_t w = ms_until(gpio->ops->now_ns(gpio->ctx), gpio->window_end);
	return w > 0x7fffffff ? 0x7fffffff : (int)w;
}

bool fscan_gpio_button_pressed(const struct fscan_gpio *gpio)
{
	return gpio && gpio->reported;
}

int fscan_gpio_set_led(struct fscan_gpio *gpio, bool on)
{
	if (!gpio)
		return -EINVAL;
	return gpio->ops->set_output(gpio->ctx, FSCAN_GPIO_LED, on);
}

int fscan_gpio_set_reset(struct fscan_gpio *gpio, bool asserted)
{
	if (!gpio)
		return -EINVAL;
	return gpio->ops->set_output(gpio->ctx, FSCAN_GPIO_RESET, asserted);
}

int fscan_gpio_pulse_reset(struct fscan_gpio *gpio, unsigned ms)
{
	if (!gpio || ms < 1 || ms > 10000)
		return -EINVAL;
	int r = gpio->ops->set_output(gpio->ctx, FSCAN_GPIO_RESET, true);
	if (r < 0)
		return r;
	struct timespec ts = {.tv_sec = ms / 1000, .tv_nsec = (long)(ms % 1000) * 1000000L};
	while (nanosleep(&ts, &ts) < 0 && errno == EINTR)
		;
	return gpio->ops->set_output(gpio->ctx, FSCAN_GPIO_RESET, false);
}
