/* Private to drivers/camera: the handle behind struct fscan_camera. */
#ifndef FACESCAN_CAMERA_INTERNAL_H
#define FACESCAN_CAMERA_INTERNAL_H

#include "facescan/camera.h"

#define FSCAN_CAMERA_MAX_TRIGGERS 16

#ifdef __cplusplus
extern "C" {
#endif

struct fscan_camera {
	const struct fscan_camera_ops *ops;
	void *ctx;
	uint32_t count;
	struct fscan_camera_config cfg;
	bool armed;
	uint32_t first_seq, n_triggers, next; /* next = index of the next trigger to collect */
	/* Frames that arrived ahead of their trigger: stash[camera][trigger index]. */
	struct fscan_camera_raw_frame stash[FSCAN_CAMERA_MAX][FSCAN_CAMERA_MAX_TRIGGERS];
	bool stashed[FSCAN_CAMERA_MAX][FSCAN_CAMERA_MAX_TRIGGERS];
	int status[FSCAN_CAMERA_MAX];
};

/* Fills a camera config's zero fields with the documented defaults. */
void fscan_camera_config_defaults(struct fscan_camera_config *cfg);

#ifdef __cplusplus
}
#endif
#endif
