#define _GNU_SOURCE
/* Fake GPIO backend: an in-memory button, LED and reset line. Raw edges queue in a ring; a pipe
 * carries one byte per queued edge so the fd polls readable exactly while edges wait. */
#include "facescan/gpio_fake.h"
#include "gpio_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define QUEUE_LEN 256

enum fake_op { OP_READ_EDGE, OP_GET_BUTTON, OP_SET_OUTPUT, OP_COUNT };

struct fake {
	pthread_mutex_t lock;
	int pipe[2];
	struct fscan_gpio_edge queue[QUEUE_LEN];
	unsigned head, len;
	bool level;              /* level after the newest queued edge */
	uint64_t offset_ns;
	bool out[2];
	int reset_count;
	int fail[OP_COUNT];
};

static uint64_t mono_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static int take_fail(struct fake *f, enum fake_op op)
{
	int err = f->fail[op];
	f->fail[op] = 0;
	return err;
}

static int fake_open(const struct fscan_gpio_config *cfg, void **ret_ctx)
{
	if (!strcmp(cfg->chip, FSCAN_GPIO_FAKE_MISSING_CHIP))
		return -ENODEV;
	struct fake *f = calloc(1, sizeof(*f));
	if (!f)
		return -ENOMEM;
	if (pipe2(f->pipe, O_CLOEXEC | O_NONBLOCK) < 0) {
		int err = -errno;
		free(f);
		return err;
	}
	pthread_mutex_init(&f->lock, NULL);
	*ret_ctx = f;
	return 0;
}

static void fake_close(void *ctx)
{
	struct fake *f = ctx;
	close(f->pipe[0]);
	close(f->pipe[1]);
	pthread_mutex_destroy(&f->lock);
	free(f);
}

static uint64_t fake_now_locked(const struct fake *f)
{
	return mono_ns() + f->offset_ns;
}

static uint64_t fake_now(void *ctx)
{
	struct fake *f = ctx;
	pthread_mutex_lock(&f->lock);
	uint64_t t = fake_now_locked(f);
	pthread_mutex_unlock(&f->lock);
	return t;
}

static int fake_read_edge(void *ctx, int timeout_ms, struct fscan_gpio_edge *ret_edge)
{
	struct fake *f = ctx;
	pthread_mutex_lock(&f->lock);
	int err = take_fail(f, OP_READ_EDGE);
	pthread_mutex_unlock(&f->lock);
	if (err)
		return err;
	struct pollfd p = {.fd = f->pipe[0], .events = POLLIN};
	int n = poll(&p, 1, timeout_ms);
	if (n < 0)
		return -errno;
	if (n == 0)
		return -ETIMEDOUT;
	char byte;
	if (read(f->pipe[0], &byte, 1) != 1)
		return -ETIMEDOUT;
	pthread_mutex_lock(&f->lock);
	int r = -ETIMEDOUT;
	if (f->len) {
		*ret_edge = f->queue[f->head];
		f->head = (f->head + 1) % QUEUE_LEN;
		f->len--;
		r = 0;
	}
	pthread_mutex_unlock(&f->lock);
	return r;
}

static int fake_get_button(void *ctx)
{
	struct fake *f = ctx;
	pthread_mutex_lock(&f->lock);
	int r = take_fail(f, OP_GET_BUTTON);
	if (!r)
		r = f->level;
	pthread_mutex_unlock(&f->lock);
	return r;
}

static int fake_set_output(void *ctx, enum fscan_gpio_output which, bool active)
{
	struct fake *f = ctx;
	if (which != FSCAN_GPIO_LED && which != FSCAN_GPIO_RESET)
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	int r = take_fail(f, OP_SET_OUTPUT);
	if (!r) {
		if (which == FSCAN_GPIO_RESET && f->out[which] && !active)
			f->reset_count++;
		f->out[which] = active;
	}
	pthread_mutex_unlock(&f->lock);
	return r;
}

static int fake_fd(void *ctx)
{
	return ((struct fake *)ctx)->pipe[0];
}

const struct fscan_gpio_ops fscan_gpio_fake_ops = {
	.name = "fake",
	.open = fake_open,
	.close = fake_close,
	.read_edge = fake_read_edge,
	.get_button = fake_get_button,
	.set_output = fake_set_output,
	.fd = fake_fd,
	.now_ns = fake_now,
};

/* ---- back doors ---- */

static struct fake *fake_of(struct fscan_gpio *gpio)
{
	if (!gpio || gpio->ops != &fscan_gpio_fake_ops)
		return NULL;
	return gpio->ctx;
}

int fscan_gpio_fake_button_at(struct fscan_gpio *gpio, bool active, uint64_t timestamp_ns)
{
	struct fake *f = fake_of(gpio);
	if (!f)
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	int r = 0;
	if (f->len == QUEUE_LEN) {
		r = -ENOBUFS;
	} else {
		f->queue[(f->head + f->len) % QUEUE_LEN] =
			(struct fscan_gpio_edge){.active = active, .timestamp_ns = timestamp_ns};
		f->len++;
		f->level = active;
		if (write(f->pipe[1], "e", 1) != 1)
			r = -EIO;
	}
	pthread_mutex_unlock(&f->lock);
	return r;
}

int fscan_gpio_fake_button(struct fscan_gpio *gpio, bool active)
{
	struct fake *f = fake_of(gpio);
	if (!f)
		return -EINVAL;
	return fscan_gpio_fake_button_at(gpio, active, fake_now(f));
}

int fscan_gpio_fake_advance_ns(struct fscan_gpio *gpio, uint64_t ns)
{
	struct fake *f = fake_of(gpio);
	if (!f)
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	f->offset_ns += ns;
	pthread_mutex_unlock(&f->lock);
	return 0;
}

uint64_t fscan_gpio_fake_now_ns(struct fscan_gpio *gpio)
{
	struct fake *f = fake_of(gpio);
	return f ? fake_now(f) : 0;
}

int fscan_gpio_fake_output(struct fscan_gpio *gpio, enum fscan_gpio_output which)
{
	struct fake *f = fake_of(gpio);
	if (!f || (which != FSCAN_GPIO_LED && which != FSCAN_GPIO_RESET))
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	int r = f->out[which];
	pthread_mutex_unlock(&f->lock);
	return r;
}

int fscan_gpio_fake_reset_count(struct fscan_gpio *gpio)
{
	struct fake *f = fake_of(gpio);
	if (!f)
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	int r = f->reset_count;
	pthread_mutex_unlock(&f->lock);
	return r;
}

int fscan_gpio_fake_fail_next(struct fscan_gpio *gpio, const char *op, int err)
{
	struct fake *f = fake_of(gpio);
	if (!f || !op || err >= 0)
		return -EINVAL;
	static const char *const names[OP_COUNT] = {"read_edge", "get_button", "set_output"};
	for (int i = 0; i < OP_COUNT; i++) {
		if (!strcmp(op, names[i])) {
			pthread_mutex_lock(&f->lock);
			f->fail[i] = err;
			pthread_mutex_unlock(&f->lock);
			return 0;
		}
	}
	return -EINVAL;
}
