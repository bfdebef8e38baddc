/* Common part of the GPIO driver: argument checks and the debounce filter over a backend's
 * raw edges. Time comes only from edge timestamps and the backend's clock, so the fake makes
 * it deterministic.
 *
 * The debounce policy is the firmware's (firmware/core/debounce.c, FW_DEBOUNCE_MS), whichever
 * side the button is wired to: a level counts once the line has held it for debounce_ms, and
 * the event is stamped when that hold completed. A glitch shorter than that (a spark on a long
 * booth cable) starts no scan; a press costs debounce_ms of latency, which a scan does not
 * notice. tests/drivers/test_debounce_policy.c feeds the same traces to both. */
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

/* True while the line holds a level the caller has not heard of: a change may settle. */
static bool unsettled(const struct fscan_gpio *gpio)
{
	return gpio->raw != gpio->reported;
}

/* Returns true with *ev filled if by `now` the line has held a new level for the window. */
static bool settle(struct fscan_gpio *gpio, uint64_t now, struct fscan_gpio_event *ev)
{
	uint64_t held_at = gpio->raw_since + gpio->debounce_ns;
	if (!unsettled(gpio) || now < held_at)
		return false;
	gpio->reported = gpio->raw;
	ev->type = gpio->raw ? FSCAN_GPIO_BUTTON_PRESSED : FSCAN_GPIO_BUTTON_RELEASED;
	ev->timestamp_ns = held_at;
	return true;
}

/* Feeds one raw edge: a change of level restarts the hold. */
static void feed(struct fscan_gpio *gpio, const struct fscan_gpio_edge *edge)
{
	if (edge->active == gpio->raw)
		return;
	gpio->raw = edge->active;
	gpio->raw_since = edge->timestamp_ns;
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
			/* Wait for the next raw edge, but not past the moment a new level has been
			 * held for the window. */
			int wait = timeout_ms;
			if (timeout_ms > 0) {
				uint64_t spent = mono_ms() - start;
				wait = spent >= (uint64_t)timeout_ms ? 0 : (int)(timeout_ms - spent);
			}
			if (unsettled(gpio)) {
				int64_t w = ms_until(gpio->ops->now_ns(gpio->ctx), gpio->raw_since + gpio->debounce_ns);
				if (wait < 0 || w < wait)
					wait = (int)w;
			}
			r = gpio->ops->read_edge(gpio->ctx, wait, &edge);
			if (r == -ETIMEDOUT)
				continue;
		}
		if (r < 0)
			return r;
		/* A level held for the window before this edge came settles first (at the end of
		 * its hold); the edge is fed on the next round. */
		if (settle(gpio, edge.timestamp_ns, &ev)) {
			gpio->pending_edge = edge;
			gpio->has_pending_edge = true;
			break;
		}
		feed(gpio, &edge);
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
	if (!unsettled(gpio))
		return -1;
	int64_t w = ms_until(gpio->ops->now_ns(gpio->ctx), gpio->raw_since + gpio->debounce_ns);
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
