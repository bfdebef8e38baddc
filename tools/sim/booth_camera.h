/* The booth simulator (tools/sim) as the render callback of the simulated camera backend
 * (fscan_camera_sim_ops): each arm renders one simulated scan — pattern frames for trigger 0,
 * texture frames for trigger 1 — of the procedural head in the simulated booth.
 *
 *   struct fscan_sim_booth *booth;
 *   fscan_sim_booth_create(&(struct fscan_sim_booth_params){.scale = 0.5}, &booth);
 *   struct fscan_camera_params p;
 *   fscan_sim_booth_camera_params(booth, &p);
 *   fscan_camera_create(&fscan_camera_sim_ops, &p, &cam);   // booth outlives cam
 *
 * 0 or -errno; fscan_sim_booth_error() keeps the simulator's message for the caller to log.
 * It lives with the simulator, not in drivers/: the driver only takes the callback, so no
 * driver includes the simulator (docs/architecture.md, "Layers").
 */
#ifndef FACESCAN_SIM_BOOTH_CAMERA_H
#define FACESCAN_SIM_BOOTH_CAMERA_H

#include "facescan/camera.h"

#ifdef __cplusplus
extern "C" {
#endif

struct fscan_sim_booth_params {
	const char *rig_path;   /* rig YAML (docs/simulator.md); NULL = the built-in default rig */
	const char *scene;      /* "default", "turned", "noisy", "dark"; NULL = "default" */
	const char *pattern_id; /* NULL = this build's default pattern */
	uint64_t seed;          /* noise seed of the first scan; scan n uses seed + n */
	double scale;           /* camera resolution scale (0 < scale <= 4); 0 = 1 */
};

struct fscan_sim_booth;

/* -EINVAL bad parameters (unknown scene, bad scale), -ENOENT rig file or pattern id unknown. */
int fscan_sim_booth_create(const struct fscan_sim_booth_params *params, struct fscan_sim_booth **ret_booth);
void fscan_sim_booth_destroy(struct fscan_sim_booth *booth); /* accepts NULL */
/* Number of cameras and their (common) sensor size. -EINVAL if the rig's cameras differ in size. */
int fscan_sim_booth_geometry(const struct fscan_sim_booth *booth, uint32_t *ret_count, uint32_t *ret_width,
			     uint32_t *ret_height);
/* Fills params for fscan_camera_sim_ops: count, size, render = fscan_sim_booth_render, user = booth. */
int fscan_sim_booth_camera_params(struct fscan_sim_booth *booth, struct fscan_camera_params *ret_params);
/* The fscan_camera_render_fn (user = the booth). Camera 0 of trigger 0 renders a new scan. */
int fscan_sim_booth_render(void *booth, uint32_t camera, uint32_t trigger_index, uint8_t *rgb, uint32_t width,
			   uint32_t height, uint32_t stride, uint64_t *ret_timestamp_ns);
/* Writes the last rendered scan as a capture set with ground_truth.ply into dir (for recon and
 * accuracy checks). -ENODATA before the first render. */
int fscan_sim_booth_write_last(const struct fscan_sim_booth *booth, const char *dir);
/* The message of the last failure ("" if none). Valid until the next call on the booth. */
const char *fscan_sim_booth_error(const struct fscan_sim_booth *booth);

#ifdef __cplusplus
}
#endif
#endif
