/* Simulated camera backend: every armed trigger "fires" at once and each camera's frame is
 * drawn by the injected render callback (fscan_camera_params.render) — the booth simulator
 * through tools/sim's fscan_sim_booth_render() (sim/booth_camera.h), or any test
 * double. The backend includes nothing of the simulator. */
#include "camera_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define READY_MAX (FSCAN_CAMERA_MAX * FSCAN_CAMERA_MAX_TRIGGERS)

struct sim {
	uint32_t count, width, height;
	fscan_camera_render_fn render;
	void *user;
	/* Frames of the current arm in arrival order of their due time; a late one does not hold
	 * back the others (cameras deliver independently). */
	struct fscan_camera_raw_frame ready[READY_MAX];
	uint64_t due_ns[READY_MAX];
	unsigned len;
	uint64_t epoch_ns;
};

static uint64_t mono_ns(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static int sim_open(const struct fscan_camera_params *p, void **ret_ctx)
{
	if (!p->render)
		return -EINVAL;
	uint32_t count = p->count ? p->count : 4;
	if (count > FSCAN_CAMERA_MAX || p->width > 16384 || p->height > 16384)
		return -EINVAL;
	struct sim *s = calloc(1, sizeof(*s));
	if (!s)
		return -ENOMEM;
	s->count = count;
	s->width = p->width ? p->width : 1600;
	s->height = p->height ? p->height : 1200;
	s->render = p->render;
	s->user = p->render_user;
	s->epoch_ns = mono_ns();
	*ret_ctx = s;
	return 0;
}

static void clear_ready(struct sim *s)
{
	for (unsigned i = 0; i < s->len; i++)
		free(s->ready[i].frame.data);
	s->len = 0;
}

static void sim_close(void *ctx)
{
	clear_ready(ctx);
	free(ctx);
}

static int sim_count(void *ctx)
{
	return (int)((struct sim *)ctx)->count;
}

static int sim_info(void *ctx, uint32_t camera, struct fscan_camera_info *ret)
{
	struct sim *s = ctx;
	memset(ret, 0, sizeof(*ret));
	snprintf(ret->id, sizeof(ret->id), "sim:%u", camera);
	snprintf(ret->model, sizeof(ret->model), "simulated");
	ret->width = s->width;
	ret->height = s->height;
	return 0;
}

static int sim_configure(void *ctx, const struct fscan_camera_config *cfg)
{
	struct sim *s = ctx;
	/* The simulated sensor has one size (the rig's). */
	if ((cfg->width && cfg->width != s->width) || (cfg->height && cfg->height != s->height))
		return -EINVAL;
	return 0;
}

static int sim_arm(void *ctx, uint32_t first_seq, uint32_t n)
{
	struct sim *s = ctx;
	clear_ready(s);
	if ((uint64_t)n * s->count > READY_MAX)
		return -EINVAL;
	const uint64_t armed_ns = mono_ns();
	for (uint32_t t = 0; t < n; t++) {
		for (uint32_t c = 0; c < s->count; c++) {
			struct fscan_camera_raw_frame f;
			memset(&f, 0, sizeof(f));
			f.frame.camera = c;
			f.frame.trigger_seq = first_seq + t;
			f.frame.width = s->width;
			f.frame.height = s->height;
			f.frame.stride = s->width * 3u;
			f.frame.timestamp_ns = s->epoch_ns + (uint64_t)(first_seq + t) * 100000000u + c * 10000u;
			f.frame.data = malloc((size_t)f.frame.stride * s->height);
			if (!f.frame.data) {
				clear_ready(s);
				return -ENOMEM;
			}
			int r = s->render(s->user, c, t, f.frame.data, s->width, s->height, f.frame.stride,
					  &f.frame.timestamp_ns);
			if (r == FSCAN_CAMERA_RENDER_DROPPED) {
				free(f.frame.data); /* the sensor never sends it */
				continue;
			}
			if (r < 0) {
				/* A render failure is that camera's failed frame, as a sensor error. */
				free(f.frame.data);
				f.frame.data = NULL;
				f.status = -EIO;
			}
			s->due_ns[s->len] = armed_ns + (r > 0 ? (uint64_t)r * 1000000u : 0);
			s->ready[s->len] = f;
			s->len++;
		}
	}
	return 0;
}

static int sim_next_frame(void *ctx, int timeout_ms, struct fscan_camera_raw_frame *ret)
{
	struct sim *s = ctx;
	const uint64_t now = mono_ns();
	unsigned best = s->len;
	for (unsigned i = 0; i < s->len; i++)
		if (best == s->len || s->due_ns[i] < s->due_ns[best])
			best = i;
	if (best == s->len || s->due_ns[best] > now + (uint64_t)(timeout_ms > 0 ? timeout_ms : 0) * 1000000u) {
		/* Nothing arrives within the timeout: wait it out, as a sensor would. */
		if (timeout_ms > 0) {
			struct timespec d = {timeout_ms / 1000, (long)(timeout_ms % 1000) * 1000000L};
			nanosleep(&d, NULL);
		}
		return -ETIMEDOUT;
	}
	if (s->due_ns[best] > now) {
		uint64_t wait = s->due_ns[best] - now;
		struct timespec d = {(time_t)(wait / 1000000000u), (long)(wait % 1000000000u)};
		nanosleep(&d, NULL);
	}
	*ret = s->ready[best];
	s->len--;
	for (unsigned i = best; i < s->len; i++) {
		s->ready[i] = s->ready[i + 1];
		s->due_ns[i] = s->due_ns[i + 1];
	}
	return 0;
}

static int sim_disarm(void *ctx)
{
	clear_ready(ctx);
	return 0;
}

const struct fscan_camera_ops fscan_camera_sim_ops = {
	.name = "sim",
	.open = sim_open,
	.close = sim_close,
	.count = sim_count,
	.info = sim_info,
	.configure = sim_configure,
	.arm = sim_arm,
	.next_frame = sim_next_frame,
	.disarm = sim_disarm,
};
