/* Fake camera backend: synthetic frames with a known pixel function and injectable faults.
 * Frames become ready per trigger ("fire"): at arm time by default, or when the test fires
 * them in manual mode. */
#include "facescan/camera_fake.h"
#include "camera_internal.h"

#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define READY_MAX (FSCAN_CAMERA_MAX * FSCAN_CAMERA_MAX_TRIGGERS)

struct fake {
	pthread_mutex_t lock;
	pthread_cond_t cond;
	uint32_t count, width, height;
	bool manual;
	bool armed;
	uint32_t first_seq, n, fired;
	int arm_count;
	enum fscan_camera_fake_fault fault[FSCAN_CAMERA_MAX][FSCAN_CAMERA_MAX_TRIGGERS];  /* next arm */
	enum fscan_camera_fake_fault active[FSCAN_CAMERA_MAX][FSCAN_CAMERA_MAX_TRIGGERS]; /* this arm */
	struct fscan_camera_raw_frame ready[READY_MAX];
	unsigned ready_head, ready_len;
	uint64_t epoch_ns;
};

uint8_t fscan_camera_fake_pixel(uint32_t camera, uint32_t trigger_seq, uint32_t x, uint32_t y, uint32_t c)
{
	return (uint8_t)(x * 3u + y * 5u + camera * 40u + trigger_seq * 17u + c * 85u);
}

static uint64_t mono_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static int fake_open(const struct fscan_camera_params *p, void **ret_ctx)
{
	uint32_t count = p->count ? p->count : 4;
	if (count > FSCAN_CAMERA_MAX)
		return -EINVAL;
	if ((p->width && p->width > 4096) || (p->height && p->height > 4096))
		return -EINVAL;
	struct fake *f = calloc(1, sizeof(*f));
	if (!f)
		return -ENOMEM;
	f->count = count;
	f->width = p->width ? p->width : 64;
	f->height = p->height ? p->height : 48;
	f->epoch_ns = mono_ns();
	pthread_mutex_init(&f->lock, NULL);
	pthread_condattr_t attr;
	pthread_condattr_init(&attr);
	pthread_condattr_setclock(&attr, CLOCK_MONOTONIC);
	pthread_cond_init(&f->cond, &attr);
	pthread_condattr_destroy(&attr);
	*ret_ctx = f;
	return 0;
}

static void clear_ready(struct fake *f)
{
	while (f->ready_len) {
		free(f->ready[f->ready_head].frame.data);
		f->ready_head = (f->ready_head + 1) % READY_MAX;
		f->ready_len--;
	}
}

static void fake_close(void *ctx)
{
	struct fake *f = ctx;
	clear_ready(f);
	pthread_cond_destroy(&f->cond);
	pthread_mutex_destroy(&f->lock);
	free(f);
}

static int fake_count(void *ctx)
{
	return (int)((struct fake *)ctx)->count;
}

static int fake_info(void *ctx, uint32_t camera, struct fscan_camera_info *ret)
{
	struct fake *f = ctx;
	memset(ret, 0, sizeof(*ret));
	snprintf(ret->id, sizeof(ret->id), "fake:%u", camera);
	snprintf(ret->model, sizeof(ret->model), "fake");
	ret->width = f->width;
	ret->height = f->height;
	return 0;
}

static int fake_configure(void *ctx, const struct fscan_camera_config *cfg)
{
	struct fake *f = ctx;
	if ((cfg->width && cfg->width > 4096) || (cfg->height && cfg->height > 4096))
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	if (cfg->width)
		f->width = cfg->width;
	if (cfg->height)
		f->height = cfg->height;
	pthread_mutex_unlock(&f->lock);
	return 0;
}

static int make_frame(struct fake *f, uint32_t cam, uint32_t idx, struct fscan_camera_raw_frame *out)
{
	enum fscan_camera_fake_fault fault = f->active[cam][idx];
	memset(out, 0, sizeof(*out));
	uint32_t seq = f->first_seq + idx;
	out->frame.camera = cam;
	out->frame.width = f->width;
	out->frame.height = f->height;
	out->frame.stride = f->width * 3u;
	out->frame.trigger_seq = fault == FSCAN_CAMERA_FAKE_WRONG_TRIGGER ? seq + 1 : seq;
	/* One flash per trigger, 100 ms apart; cameras 10 us apart. */
	out->frame.timestamp_ns = f->epoch_ns + (uint64_t)seq * 100000000u + cam * 10000u;
	if (fault == FSCAN_CAMERA_FAKE_LATE)
		out->frame.timestamp_ns += 50000000u;
	if (fault == FSCAN_CAMERA_FAKE_DROPPED) {
		out->status = -EIO;
		return 0;
	}
	out->frame.data = malloc((size_t)out->frame.stride * f->height);
	if (!out->frame.data)
		return -ENOMEM;
	for (uint32_t y = 0; y < f->height; y++) {
		uint8_t *row = out->frame.data + (size_t)y * out->frame.stride;
		for (uint32_t x = 0; x < f->width; x++)
			for (uint32_t c = 0; c < 3; c++)
				row[x * 3 + c] = fscan_camera_fake_pixel(cam, out->frame.trigger_seq, x, y, c);
	}
	return 0;
}

/* Makes the next trigger's frames ready. Called with the lock held. */
static int fire_locked(struct fake *f)
{
	if (!f->armed || f->fired >= f->n)
		return -ENODATA;
	uint32_t idx = f->fired++;
	for (uint32_t c = 0; c < f->count; c++) {
		if (f->active[c][idx] == FSCAN_CAMERA_FAKE_TIMEOUT)
			continue;
		struct fscan_camera_raw_frame fr;
		int r = make_frame(f, c, idx, &fr);
		if (r < 0)
			return r;
		f->ready[(f->ready_head + f->ready_len) % READY_MAX] = fr;
		f->ready_len++;
	}
	pthread_cond_broadcast(&f->cond);
	return 0;
}

static int fake_arm(void *ctx, uint32_t first_seq, uint32_t n)
{
	struct fake *f = ctx;
	pthread_mutex_lock(&f->lock);
	clear_ready(f);
	f->armed = true;
	f->first_seq = first_seq;
	f->n = n;
	f->fired = 0;
	f->arm_count++;
	/* Injected faults apply to one arm only. */
	memcpy(f->active, f->fault, sizeof(f->active));
	memset(f->fault, 0, sizeof(f->fault));
	int r = 0;
	if (!f->manual)
		while (!r && f->fired < f->n)
			r = fire_locked(f);
	pthread_mutex_unlock(&f->lock);
	return r;
}

static int fake_next_frame(void *ctx, int timeout_ms, struct fscan_camera_raw_frame *ret)
{
	struct fake *f = ctx;
	struct timespec deadline;
	clock_gettime(CLOCK_MONOTONIC, &deadline);
	if (timeout_ms > 0) {
		deadline.tv_sec += timeout_ms / 1000;
		deadline.tv_nsec += (long)(timeout_ms % 1000) * 1000000L;
		if (deadline.tv_nsec >= 1000000000L) {
			deadline.tv_sec++;
			deadline.tv_nsec -= 1000000000L;
		}
	}
	pthread_mutex_lock(&f->lock);
	while (!f->ready_len && timeout_ms != 0) {
		int r = timeout_ms < 0 ? pthread_cond_wait(&f->cond, &f->lock)
				       : pthread_cond_timedwait(&f->cond, &f->lock, &deadline);
		if (r == ETIMEDOUT)
			break;
	}
	int r = -ETIMEDOUT;
	if (f->ready_len) {
		*ret = f->ready[f->ready_head];
		f->ready_head = (f->ready_head + 1) % READY_MAX;
		f->ready_len--;
		r = 0;
	}
	pthread_mutex_unlock(&f->lock);
	return r;
}

static int fake_disarm(void *ctx)
{
	struct fake *f = ctx;
	pthread_mutex_lock(&f->lock);
	clear_ready(f);
	f->armed = false;
	pthread_mutex_unlock(&f->lock);
	return 0;
}

const struct fscan_camera_ops fscan_camera_fake_ops = {
	.name = "fake",
	.open = fake_open,
	.close = fake_close,
	.count = fake_count,
	.info = fake_info,
	.configure = fake_configure,
	.arm = fake_arm,
	.next_frame = fake_next_frame,
	.disarm = fake_disarm,
};

/* ---- back doors ---- */

static struct fake *fake_of(struct fscan_camera *cam)
{
	return cam && cam->ops == &fscan_camera_fake_ops ? cam->ctx : NULL;
}

int fscan_camera_fake_inject(struct fscan_camera *cam, uint32_t camera, uint32_t trigger_index,
			     enum fscan_camera_fake_fault fault)
{
	struct fake *f = fake_of(cam);
	if (!f || camera >= f->count || trigger_index >= FSCAN_CAMERA_MAX_TRIGGERS ||
	    fault < FSCAN_CAMERA_FAKE_OK || fault > FSCAN_CAMERA_FAKE_LATE)
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	f->fault[camera][trigger_index] = fault;
	pthread_mutex_unlock(&f->lock);
	return 0;
}

int fscan_camera_fake_set_manual(struct fscan_camera *cam, bool manual)
{
	struct fake *f = fake_of(cam);
	if (!f)
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	f->manual = manual;
	pthread_mutex_unlock(&f->lock);
	return 0;
}

int fscan_camera_fake_fire(struct fscan_camera *cam)
{
	struct fake *f = fake_of(cam);
	if (!f)
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	int r = fire_locked(f);
	pthread_mutex_unlock(&f->lock);
	return r;
}

int fscan_camera_fake_arm_count(struct fscan_camera *cam)
{
	struct fake *f = fake_of(cam);
	if (!f)
		return -EINVAL;
	pthread_mutex_lock(&f->lock);
	int r = f->arm_count;
	pthread_mutex_unlock(&f->lock);
	return r;
}
