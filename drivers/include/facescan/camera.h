/* facescan camera driver: N cameras behind one handle, captured in lockstep by the MCU's
 * hardware trigger.
 *
 * The cycle for one scan:
 *   fscan_camera_configure()          once: size, fixed exposure and gain, external trigger
 *   fscan_camera_arm(first_seq, n)    queue a request per camera per trigger BEFORE the MCU fires
 *   ... the MCU fires n triggers ...
 *   fscan_camera_collect() n times    one frame set per trigger, in trigger order
 *   fscan_camera_disarm()             cancel what is still queued (after an error or abort)
 *
 * Trigger numbering: triggers are numbered by the caller (the MCU's sequence report numbers
 * them too); arm() says which number the next trigger gets. Scan convention (capture format):
 * trigger 0 of a scan = the pattern shot (cam{i}.png), trigger 1 = the texture shot
 * (cam{i}_texture.png).
 *
 * Backends:
 *   fscan_camera_libcamera_ops  real cameras (libcamera; C++ behind this C interface)
 *   fscan_camera_replay_ops     a saved capture set directory (docs/capture-format.md)
 *   fscan_camera_sim_ops        renders through an injected callback (the booth simulator)
 *   fscan_camera_fake_ops       synthetic frames with fault injection (facescan/camera_fake.h)
 *   fscan_camera_isolated_ops   another backend (libcamera by default) run in a child process:
 *                               a camera stack that aborts or hangs fails the ops (-ENODEV,
 *                               -ETIMEDOUT), not the caller's process
 * The common code (camera.c) groups frames by trigger and checks them, so each backend only
 * delivers single frames.
 *
 * Every function returns 0 or a negative errno; nothing here logs or exits. One thread per
 * handle.
 */
#ifndef FACESCAN_CAMERA_H
#define FACESCAN_CAMERA_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FSCAN_CAMERA_MAX 8

/* One frame: 8-bit RGB, row-major, `stride` bytes per row (>= 3 * width). */
struct fscan_frame {
	uint8_t *data;
	uint32_t width, height, stride;
	uint64_t timestamp_ns;  /* sensor timestamp (start of exposure), CLOCK_MONOTONIC-like */
	uint32_t trigger_seq;   /* which trigger exposed it */
	uint32_t camera;        /* index 0..count-1 */
};

/* All cameras' frames of one trigger; frames[i] comes from camera i. Owned by the caller:
 * free with fscan_frame_set_free(). */
struct fscan_frame_set {
	uint32_t trigger_seq;
	uint32_t count;
	uint64_t skew_ns;        /* latest minus earliest timestamp in the set */
	struct fscan_frame frames[FSCAN_CAMERA_MAX];
};
void fscan_frame_set_free(struct fscan_frame_set *set); /* accepts NULL */

/* The render callback the simulated backend draws frames with (the booth simulator, or any
 * test double). Fills `rgb` (width x height, `stride` bytes per row) with what camera `camera`
 * sees at trigger `trigger_index` of the current arm (0 = first), and may set *ret_timestamp_ns
 * (it is preset to a synthetic time). Returns 0 (the frame arrives at once), a count of
 * milliseconds > 0 (it arrives that long after the arm: a slow sensor or link),
 * FSCAN_CAMERA_RENDER_DROPPED (it never arrives: collect times out on that camera), or -errno
 * (the camera reports a failed frame). */
#define FSCAN_CAMERA_RENDER_DROPPED 0x7fffffff
typedef int (*fscan_camera_render_fn)(void *user, uint32_t camera, uint32_t trigger_index,
				      uint8_t *rgb, uint32_t width, uint32_t height, uint32_t stride,
				      uint64_t *ret_timestamp_ns);

/* Backend-specific open parameters; each backend reads the fields it names and ignores the
 * rest (zeroed struct = defaults). */
struct fscan_camera_params {
	/* replay: the capture set directory. libcamera: optional comma-separated list of camera
	 * ids to use, in index order (NULL = every camera found, sorted by id). */
	const char *source;
	/* fake, sim: number of cameras (1..FSCAN_CAMERA_MAX; 0 = 4). */
	uint32_t count;
	/* fake, sim: sensor size (0 = 64 x 48 for the fake, 1600 x 1200 for sim). */
	uint32_t width, height;
	/* sim: the renderer. */
	fscan_camera_render_fn render;
	void *render_user;
	/* isolated: the backend the child process runs with these same params (NULL = libcamera). */
	const struct fscan_camera_ops *isolated_inner;
};

struct fscan_camera_config {
	uint32_t width, height;   /* 0 = the sensor's size */
	uint32_t exposure_us;     /* fixed exposure; 0 = 8000 */
	float analogue_gain;      /* fixed gain; 0 = 1.0 */
	uint32_t max_skew_us;     /* frames of one trigger must lie within this; 0 = 2000 */
	bool external_trigger;    /* true in the booth; the fake/sim/replay ignore it */
};

/* C++ callers: the function fscan_camera_info() hides this tag, so write
 * `struct fscan_camera_info info;`. */
struct fscan_camera_info {
	char id[64];             /* stable id (libcamera id, "replay:cam0", "fake:0") */
	char model[32];
	uint32_t width, height;  /* the sensor's (or the configured) size */
};

/* A single frame as a backend delivers it (common code groups them). */
struct fscan_camera_raw_frame {
	struct fscan_frame frame;  /* data malloc'ed by the backend, ownership passes to caller */
	int status;                /* 0, or -EIO when the camera reported a failed/dropped frame */
};

/* The backend interface. */
struct fscan_camera_ops {
	const char *name;
	/* -ENODEV when there is no camera, -ENOENT/-EINVAL for a bad source. */
	int (*open)(const struct fscan_camera_params *params, void **ret_ctx);
	void (*close)(void *ctx);
	int (*count)(void *ctx);
	int (*info)(void *ctx, uint32_t camera, struct fscan_camera_info *ret_info);
	int (*configure)(void *ctx, const struct fscan_camera_config *cfg);
	/* Queues requests for triggers first_seq .. first_seq + n - 1 on every camera. */
	int (*arm)(void *ctx, uint32_t first_seq, uint32_t n_triggers);
	/* Next frame from any camera: 0, -ETIMEDOUT when none within timeout_ms. */
	int (*next_frame)(void *ctx, int timeout_ms, struct fscan_camera_raw_frame *ret_frame);
	int (*disarm)(void *ctx);
};

extern const struct fscan_camera_ops fscan_camera_libcamera_ops;
extern const struct fscan_camera_ops fscan_camera_replay_ops;
extern const struct fscan_camera_ops fscan_camera_sim_ops;
extern const struct fscan_camera_ops fscan_camera_fake_ops;
extern const struct fscan_camera_ops fscan_camera_isolated_ops;

struct fscan_camera;

/* Opens the cameras. On success free *ret_cam with fscan_camera_destroy().
 * -EINVAL bad arguments, -ENODEV no camera (libcamera on a machine without one),
 * -ENOENT replay source missing, -EBADMSG replay source malformed. */
int fscan_camera_create(const struct fscan_camera_ops *ops, const struct fscan_camera_params *params,
			struct fscan_camera **ret_cam);
void fscan_camera_destroy(struct fscan_camera *cam); /* accepts NULL; disarms first */

int fscan_camera_count(const struct fscan_camera *cam);
int fscan_camera_info(struct fscan_camera *cam, uint32_t camera, struct fscan_camera_info *ret_info);
/* -EINVAL unsupported size/exposure/gain, -EBUSY while armed. */
int fscan_camera_configure(struct fscan_camera *cam, const struct fscan_camera_config *cfg);
/* -EBUSY already armed, -EINVAL n_triggers 0 or > 16, -ENODATA (replay) no such shot. */
int fscan_camera_arm(struct fscan_camera *cam, uint32_t first_seq, uint32_t n_triggers);
/* The frame set of the next trigger. On success *ret_set is the caller's.
 *  -ETIMEDOUT  some camera delivered nothing for this trigger within timeout_ms
 *  -EIO        some camera reported a dropped/failed frame
 *  -EXDEV      a frame from another trigger arrived, or the set's timestamps spread more than
 *              max_skew_us (frames not from one flash)
 *  -ENODATA    not armed, or every armed trigger was collected
 * After an error fscan_camera_frame_status() tells which camera failed how; the remaining
 * triggers of this arm are abandoned (disarm, then arm again). */
int fscan_camera_collect(struct fscan_camera *cam, int timeout_ms, struct fscan_frame_set **ret_set);
int fscan_camera_disarm(struct fscan_camera *cam);
/* Status of camera i in the last collect: 0, -ETIMEDOUT, -EIO, -EXDEV; -EINVAL bad index. */
int fscan_camera_frame_status(const struct fscan_camera *cam, uint32_t camera);

#ifdef __cplusplus
}
#endif
#endif
