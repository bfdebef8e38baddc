/* Common part of the camera driver: argument checks, and grouping single frames into one
 * frame set per trigger with the checks for missing, failed and foreign frames. */
#include "camera_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

void fscan_camera_config_defaults(struct fscan_camera_config *cfg)
{
	if (!cfg->exposure_us)
		cfg->exposure_us = 8000;
	if (cfg->analogue_gain <= 0.0f)
		cfg->analogue_gain = 1.0f;
	if (!cfg->max_skew_us)
		cfg->max_skew_us = 2000;
}

void fscan_frame_set_free(struct fscan_frame_set *set)
{
	if (!set)
		return;
	for (uint32_t i = 0; i < set->count && i < FSCAN_CAMERA_MAX; i++)
		free(set->frames[i].data);
	free(set);
}

int fscan_camera_create(const struct fscan_camera_ops *ops, const struct fscan_camera_params *params,
			struct fscan_camera **ret_cam)
{
	static const struct fscan_camera_params no_params;
	if (!ops || !ret_cam || !ops->open)
		return -EINVAL;
	struct fscan_camera *cam = calloc(1, sizeof(*cam));
	if (!cam)
		return -ENOMEM;
	cam->ops = ops;
	int r = ops->open(params ? params : &no_params, &cam->ctx);
	if (r < 0)
		goto err_free;
	r = ops->count(cam->ctx);
	if (r < 0)
		goto err_close;
	if (r == 0 || r > FSCAN_CAMERA_MAX) {
		r = r == 0 ? -ENODEV : -E2BIG;
		goto err_close;
	}
	cam->count = (uint32_t)r;
	fscan_camera_config_defaults(&cam->cfg);
	*ret_cam = cam;
	return 0;

err_close:
	ops->close(cam->ctx);
err_free:
	free(cam);
	return r;
}

static void drop_stash(struct fscan_camera *cam)
{
	for (uint32_t c = 0; c < FSCAN_CAMERA_MAX; c++)
		for (uint32_t t = 0; t < FSCAN_CAMERA_MAX_TRIGGERS; t++)
			if (cam->stashed[c][t]) {
				free(cam->stash[c][t].frame.data);
				cam->stashed[c][t] = false;
			}
}

void fscan_camera_destroy(struct fscan_camera *cam)
{
	if (!cam)
		return;
	if (cam->armed)
		cam->ops->disarm(cam->ctx);
	drop_stash(cam);
	cam->ops->close(cam->ctx);
	free(cam);
}

int fscan_camera_count(const struct fscan_camera *cam)
{
	return cam ? (int)cam->count : -EINVAL;
}

int fscan_camera_info(struct fscan_camera *cam, uint32_t camera, struct fscan_camera_info *ret_info)
{
	if (!cam || !ret_info || camera >= cam->count)
		return -EINVAL;
	return cam->ops->info(cam->ctx, camera, ret_info);
}

int fscan_camera_configure(struct fscan_camera *cam, const struct fscan_camera_config *cfg)
{
	if (!cam || !cfg)
		return -EINVAL;
	if (cam->armed)
		return -EBUSY;
	struct fscan_camera_config c = *cfg;
	fscan_camera_config_defaults(&c);
	if (c.analogue_gain > 64.0f || c.exposure_us > 1000000u || c.width > 16384 || c.height > 16384)
		return -EINVAL;
	int r = cam->ops->configure(cam->ctx, &c);
	if (r < 0)
		return r;
	cam->cfg = c;
	return 0;
}

int fscan_camera_arm(struct fscan_camera *cam, uint32_t first_seq, uint32_t n_triggers)
{
	if (!cam)
		return -EINVAL;
	if (cam->armed)
		return -EBUSY;
	if (n_triggers == 0 || n_triggers > FSCAN_CAMERA_MAX_TRIGGERS || first_seq > UINT32_MAX - n_triggers)
		return -EINVAL;
	int r = cam->ops->arm(cam->ctx, first_seq, n_triggers);
	if (r < 0)
		return r;
	for (uint32_t c = 0; c < FSCAN_CAMERA_MAX; c++)
		cam->status[c] = 0;
	cam->armed = true;
	cam->first_seq = first_seq;
	cam->n_triggers = n_triggers;
	cam->next = 0;
	return 0;
}

int fscan_camera_disarm(struct fscan_camera *cam)
{
	if (!cam)
		return -EINVAL;
	drop_stash(cam);
	if (!cam->armed)
		return 0;
	cam->armed = false;
	return cam->ops->disarm(cam->ctx);
}

int fscan_camera_frame_status(const struct fscan_camera *cam, uint32_t camera)
{
	if (!cam || camera >= cam->count)
		return -EINVAL;
	return cam->status[camera];
}

static uint64_t mono_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

/* Marks the frames whose timestamp lies further than max_skew from the median: they were not
 * exposed by the same flash as the others. Returns how many were marked. */
static int check_skew(struct fscan_camera *cam, struct fscan_frame_set *set)
{
	uint64_t ts[FSCAN_CAMERA_MAX];
	uint64_t lo = UINT64_MAX, hi = 0;
	for (uint32_t c = 0; c < set->count; c++) {
		ts[c] = set->frames[c].timestamp_ns;
		lo = ts[c] < lo ? ts[c] : lo;
		hi = ts[c] > hi ? ts[c] : hi;
	}
	set->skew_ns = hi - lo;
	uint64_t max_ns = (uint64_t)cam->cfg.max_skew_us * 1000u;
	if (set->skew_ns <= max_ns)
		return 0;
	/* Insertion sort of a copy for the median. */
	uint64_t s[FSCAN_CAMERA_MAX];
	memcpy(s, ts, sizeof(s));
	for (uint32_t i = 1; i < set->count; i++)
		for (uint32_t j = i; j > 0 && s[j - 1] > s[j]; j--) {
			uint64_t t = s[j];
			s[j] = s[j - 1];
			s[j - 1] = t;
		}
	uint64_t med = s[(set->count - 1) / 2];
	int marked = 0;
	for (uint32_t c = 0; c < set->count; c++) {
		uint64_t d = ts[c] > med ? ts[c] - med : med - ts[c];
		if (d > max_ns) {
			cam->status[c] = -EXDEV;
			marked++;
		}
	}
	if (!marked) { /* two cameras: blame the later one */
		for (uint32_t c = 0; c < set->count; c++)
			if (ts[c] == hi) {
				cam->status[c] = -EXDEV;
				marked++;
				break;
			}
	}
	return marked;
}

/* Places one delivered frame; returns 0, or the error it shows (status[] set). */
static int place(struct fscan_camera *cam, struct fscan_frame_set *set, bool *have,
		 struct fscan_camera_raw_frame *f)
{
	uint32_t c = f->frame.camera;
	uint32_t seq = cam->first_seq + cam->next;
	uint32_t q = f->frame.trigger_seq;
	if (c >= cam->count) {
		free(f->frame.data);
		return -EIO;
	}
	uint32_t t = q - cam->first_seq;
	bool later = q > seq && q >= cam->first_seq && t < cam->n_triggers;
	if (f->status < 0 && !later) {
		free(f->frame.data);
		cam->status[c] = f->status;
		return f->status;
	}
	if (q == seq && !have[c]) {
		set->frames[c] = f->frame;
		have[c] = true;
		return 0;
	}
	/* A later trigger's frame (cameras need not take turns): keep it for that trigger. If
	 * this camera then never delivers this trigger's frame, the wait times out. */
	if (later && !cam->stashed[c][t]) {
		cam->stash[c][t] = *f;
		cam->stashed[c][t] = true;
		return 0;
	}
	/* An earlier trigger's frame, one beyond this arm, or a second frame for a slot. */
	free(f->frame.data);
	cam->status[c] = -EXDEV;
	return -EXDEV;
}

int fscan_camera_collect(struct fscan_camera *cam, int timeout_ms, struct fscan_frame_set **ret_set)
{
	if (!cam || !ret_set)
		return -EINVAL;
	if (!cam->armed || cam->next >= cam->n_triggers)
		return -ENODATA;
	struct fscan_frame_set *set = calloc(1, sizeof(*set));
	if (!set)
		return -ENOMEM;
	bool have[FSCAN_CAMERA_MAX] = {false};
	uint32_t got = 0;
	int r = 0;
	set->trigger_seq = cam->first_seq + cam->next;
	set->count = cam->count;
	for (uint32_t c = 0; c < cam->count; c++)
		cam->status[c] = 0;

	/* Frames that came early for this trigger. */
	for (uint32_t c = 0; c < cam->count && !r; c++) {
		if (!cam->stashed[c][cam->next])
			continue;
		struct fscan_camera_raw_frame f = cam->stash[c][cam->next];
		cam->stashed[c][cam->next] = false;
		r = place(cam, set, have, &f);
		got += have[c];
	}
	uint64_t start = mono_ms();
	while (!r && got < cam->count) {
		int wait = timeout_ms;
		if (timeout_ms >= 0) {
			uint64_t spent = mono_ms() - start;
			wait = spent >= (uint64_t)timeout_ms ? 0 : (int)(timeout_ms - spent);
		}
		struct fscan_camera_raw_frame f;
		memset(&f, 0, sizeof(f));
		int n = cam->ops->next_frame(cam->ctx, wait, &f);
		if (n == -ETIMEDOUT) {
			/* With no deadline, a backend that times out anyway knows nothing will come. */
			if (timeout_ms < 0 || mono_ms() - start >= (uint64_t)timeout_ms) {
				for (uint32_t c = 0; c < cam->count; c++)
					if (!have[c])
						cam->status[c] = -ETIMEDOUT;
				r = -ETIMEDOUT;
			}
			continue;
		}
		if (n < 0) {
			/* The backend failed (an isolated camera stack died): every camera still
			 * owing a frame failed the same way. */
			for (uint32_t c = 0; c < cam->count; c++)
				if (!have[c])
					cam->status[c] = n;
			r = n;
			break;
		}
		uint32_t c = f.frame.camera;
		bool had = c < cam->count && have[c];
		r = place(cam, set, have, &f);
		if (!r && c < cam->count && have[c] && !had)
			got++;
	}
	if (!r && check_skew(cam, set))
		r = -EXDEV;
	if (r < 0) {
		/* The remaining triggers of this arm are abandoned. */
		set->count = cam->count;
		for (uint32_t c = 0; c < cam->count; c++)
			if (!have[c])
				set->frames[c].data = NULL;
		fscan_frame_set_free(set);
		drop_stash(cam);
		cam->ops->disarm(cam->ctx);
		cam->armed = false;
		return r;
	}
	cam->next++;
	if (cam->next == cam->n_triggers) {
		cam->ops->disarm(cam->ctx);
		cam->armed = false;
		drop_stash(cam);
	}
	*ret_set = set;
	return 0;
}
