/* Camera driver: one contract, run on the fake backend (what facescand's camera_backend = fake
 * and the daemon tests use) and on the simulated backend (a render callback, as the booth
 * simulator draws). It is what DriverCameras relies on: a pattern and a texture trigger
 * collected as one set each, every camera's frame stamped with its trigger and within the skew
 * limit, -ENODATA past the last trigger, a disarm abandoning the rest, and the faults the daemon
 * tests inject through the fake — a camera that never delivers, a frame not of the trigger's
 * flash — reported by the other backend the same way. libcamera, which takes no injected
 * fault, has the healthy path in test_camera_libcamera (skips 77 without a camera, as here) and
 * in the VM tier on vimc (tests/vm). */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>

#include "facescan/camera.h"
#include "facescan/camera_fake.h"

#define CAMERAS 4
#define LATE_NS 50000000u /* far beyond the default skew limit (2 ms) */

/* ---- the simulated backend's faults, through its render callback ---- */

struct sim_faults {
	int never_delivers; /* camera whose frame never arrives, or -1 */
	int late;           /* camera whose timestamp is LATE_NS late, or -1 */
};

static int sim_render(void *user, uint32_t camera, uint32_t trigger_index, uint8_t *rgb, uint32_t width,
		      uint32_t height, uint32_t stride, uint64_t *ret_timestamp_ns)
{
	struct sim_faults *f = user;
	for (uint32_t y = 0; y < height; y++)
		memset(rgb + (size_t)y * stride, (int)(camera * 16 + trigger_index), (size_t)width * 3);
	if (trigger_index == 0 && (int)camera == f->never_delivers)
		return FSCAN_CAMERA_RENDER_DROPPED;
	if (trigger_index == 0 && (int)camera == f->late)
		*ret_timestamp_ns += LATE_NS;
	return 0;
}

/* ---- the benches ---- */

enum backend { FAKE, SIM };

struct bench {
	enum backend backend;
	struct fscan_camera *cam;
	struct sim_faults sim; /* SIM: read by the render at each arm */
};

static struct sim_faults healthy = {-1, -1};

static void bench_open(struct bench *b, enum backend backend)
{
	memset(b, 0, sizeof(*b));
	b->backend = backend;
	b->sim = healthy;
	struct fscan_camera_params p = {.count = CAMERAS, .width = 16, .height = 12};
	const struct fscan_camera_ops *ops = &fscan_camera_fake_ops;
	if (backend == SIM) {
		ops = &fscan_camera_sim_ops;
		p.render = sim_render;
		p.render_user = &b->sim;
	}
	assert_int_equal(fscan_camera_create(ops, &p, &b->cam), 0);
	struct fscan_camera_config cfg = {.exposure_us = 5000, .external_trigger = true};
	assert_int_equal(fscan_camera_configure(b->cam, &cfg), 0);
}

/* The next arm: camera `camera` never delivers its first trigger's frame. */
static void inject_never_delivers(struct bench *b, uint32_t camera)
{
	if (b->backend == FAKE)
		assert_int_equal(fscan_camera_fake_inject(b->cam, camera, 0, FSCAN_CAMERA_FAKE_TIMEOUT), 0);
	else
		b->sim.never_delivers = (int)camera;
}

/* The next arm: camera `camera`'s first frame is not of the others' flash (50 ms off). */
static void inject_late(struct bench *b, uint32_t camera)
{
	if (b->backend == FAKE)
		assert_int_equal(fscan_camera_fake_inject(b->cam, camera, 0, FSCAN_CAMERA_FAKE_LATE), 0);
	else
		b->sim.late = (int)camera;
}

static long ms_since(const struct timespec *t0)
{
	struct timespec t1;
	clock_gettime(CLOCK_MONOTONIC, &t1);
	return (t1.tv_sec - t0->tv_sec) * 1000 + (t1.tv_nsec - t0->tv_nsec) / 1000000;
}

/* ---- the contract ---- */

/* Arms triggers first_seq, first_seq + 1 and collects both: one full set each. */
static void collect_pattern_and_texture(struct fscan_camera *cam, uint32_t first_seq)
{
	const uint32_t n = CAMERAS;
	assert_int_equal(fscan_camera_count(cam), CAMERAS);
	assert_int_equal(fscan_camera_arm(cam, first_seq, 2), 0);
	for (uint32_t t = 0; t < 2; t++) {
		struct fscan_frame_set *set = NULL;
		assert_int_equal(fscan_camera_collect(cam, 5000, &set), 0);
		assert_int_equal(set->trigger_seq, first_seq + t);
		assert_int_equal(set->count, n);
		assert_true(set->skew_ns <= 2000000u);
		for (uint32_t c = 0; c < n; c++) {
			const struct fscan_frame *f = &set->frames[c];
			assert_int_equal(f->camera, c);
			assert_int_equal(f->trigger_seq, first_seq + t);
			assert_non_null(f->data);
			assert_true(f->width > 0 && f->height > 0 && f->stride >= 3 * f->width);
		}
		fscan_frame_set_free(set);
	}
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(cam, 10, &set), -ENODATA);
	assert_null(set);
}

/* After a fault: disarmed, the fault gone, the next scan is whole. */
static void back_to_healthy(struct bench *b)
{
	assert_int_equal(fscan_camera_disarm(b->cam), 0);
	b->sim = healthy;
	collect_pattern_and_texture(b->cam, 2);
}

static void contract_two_triggers(struct bench *b)
{
	collect_pattern_and_texture(b->cam, 0);
	/* Disarmed midway, then armed again: the next scan is whole. */
	assert_int_equal(fscan_camera_arm(b->cam, 2, 2), 0);
	assert_int_equal(fscan_camera_disarm(b->cam), 0);
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(b->cam, 10, &set), -ENODATA);
	collect_pattern_and_texture(b->cam, 4);
}

static void contract_never_delivers(struct bench *b)
{
	inject_never_delivers(b, 2);
	assert_int_equal(fscan_camera_arm(b->cam, 0, 2), 0);
	struct timespec t0;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(b->cam, 200, &set), -ETIMEDOUT);
	assert_true(ms_since(&t0) >= 190);
	assert_null(set);
	assert_int_equal(fscan_camera_frame_status(b->cam, 2), -ETIMEDOUT);
	assert_int_equal(fscan_camera_frame_status(b->cam, 0), 0);
	back_to_healthy(b);
}

static void contract_late_frame(struct bench *b)
{
	inject_late(b, 1);
	assert_int_equal(fscan_camera_arm(b->cam, 0, 2), 0);
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(b->cam, 1000, &set), -EXDEV);
	assert_null(set);
	assert_int_equal(fscan_camera_frame_status(b->cam, 1), -EXDEV);
	assert_int_equal(fscan_camera_frame_status(b->cam, 0), 0);
	back_to_healthy(b);
}

static void run(enum backend backend, void (*contract)(struct bench *))
{
	struct bench b;
	bench_open(&b, backend);
	contract(&b);
	fscan_camera_destroy(b.cam);
}

static void test_fake_two_triggers(void **s) { (void)s; run(FAKE, contract_two_triggers); }
static void test_sim_two_triggers(void **s) { (void)s; run(SIM, contract_two_triggers); }
static void test_fake_never_delivers(void **s) { (void)s; run(FAKE, contract_never_delivers); }
static void test_sim_never_delivers(void **s) { (void)s; run(SIM, contract_never_delivers); }
static void test_fake_late_frame(void **s) { (void)s; run(FAKE, contract_late_frame); }
static void test_sim_late_frame(void **s) { (void)s; run(SIM, contract_late_frame); }

/* A frame stamped with another trigger is a fault only the fake can make (a real sensor's
 * frame carries the sequence it was exposed at); the driver's common code reports it as the
 * late frame above, -EXDEV on that camera, so the daemon sees one kind of failure for both. */
static void test_fake_wrong_trigger_is_exdev(void **s)
{
	(void)s;
	struct bench b;
	bench_open(&b, FAKE);
	assert_int_equal(fscan_camera_fake_inject(b.cam, 1, 0, FSCAN_CAMERA_FAKE_WRONG_TRIGGER), 0);
	assert_int_equal(fscan_camera_arm(b.cam, 0, 2), 0);
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(b.cam, 200, &set), -EXDEV);
	assert_int_equal(fscan_camera_frame_status(b.cam, 1), -EXDEV);
	fscan_camera_destroy(b.cam);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_fake_two_triggers),
		cmocka_unit_test(test_sim_two_triggers),
		cmocka_unit_test(test_fake_never_delivers),
		cmocka_unit_test(test_sim_never_delivers),
		cmocka_unit_test(test_fake_late_frame),
		cmocka_unit_test(test_sim_late_frame),
		cmocka_unit_test(test_fake_wrong_trigger_is_exdev),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
