/* Back doors of the fake camera backend (fscan_camera_fake_ops): synthetic frames whose pixels
 * are a known function of (camera, trigger, x, y), and fault injection. Every function takes a
 * handle created with fscan_camera_fake_ops (-EINVAL otherwise) and may be called from another
 * thread than the one collecting.
 *
 * By default every armed trigger "fires" at once: its frames are ready right after arm().
 * In manual mode frames appear only when the test calls fscan_camera_fake_fire(), which is how
 * a test checks that requests were queued before the trigger.
 */
#ifndef FACESCAN_CAMERA_FAKE_H
#define FACESCAN_CAMERA_FAKE_H

#include "facescan/camera.h"

#ifdef __cplusplus
extern "C" {
#endif

enum fscan_camera_fake_fault {
	FSCAN_CAMERA_FAKE_OK = 0,
	FSCAN_CAMERA_FAKE_TIMEOUT,        /* the camera never delivers this trigger's frame */
	FSCAN_CAMERA_FAKE_DROPPED,        /* it delivers a failed frame (status -EIO) */
	FSCAN_CAMERA_FAKE_WRONG_TRIGGER,  /* it delivers a frame stamped with the next trigger */
	FSCAN_CAMERA_FAKE_LATE,           /* its timestamp is 50 ms after the others' */
};

/* Applies `fault` to camera `camera` at trigger index `trigger_index` (0 = first trigger of the
 * next arm; faults are cleared by each arm once used). */
int fscan_camera_fake_inject(struct fscan_camera *cam, uint32_t camera, uint32_t trigger_index,
			     enum fscan_camera_fake_fault fault);
/* Manual trigger mode on/off (off by default). */
int fscan_camera_fake_set_manual(struct fscan_camera *cam, bool manual);
/* Fires the next armed trigger (manual mode): its frames become ready. -ENODATA if none armed. */
int fscan_camera_fake_fire(struct fscan_camera *cam);
/* How many times arm() succeeded. */
int fscan_camera_fake_arm_count(struct fscan_camera *cam);
/* The value the fake puts at channel c (0 R, 1 G, 2 B) of pixel (x, y). */
uint8_t fscan_camera_fake_pixel(uint32_t camera, uint32_t trigger_seq, uint32_t x, uint32_t y,
				uint32_t c);

#ifdef __cplusplus
}
#endif
#endif
