/* Camera driver common code through the fake backend: grouping one trigger's frames across
 * cameras, and each injected fault reported as documented. */
#include <errno.h>
#include <pthread.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <time.h>
#include <cmocka.h>

#include "facescan/camera.h"
#include "facescan/camera_fake.h"

static int setup(void **state)
{
	struct fscan_camera_params p = {.count = 4, .width = 32, .height = 24};
	struct fscan_camera *cam;
	assert_int_equal(fscan_camera_create(&fscan_camera_fake_ops, &p, &cam), 0);
	struct fscan_camera_config cfg = {.exposure_us = 5000, .analogue_gain = 2.0f, .external_trigger = true};
	assert_int_equal(fscan_camera_configure(cam, &cfg), 0);
	*state = cam;
	return 0;
}

static int teardown(void **state)
{
	fscan_camera_destroy(*state);
	return 0;
}

static void check_pixels(const struct fscan_frame *f, uint32_t cam, uint32_t seq)
{
	assert_int_equal(f->camera, cam);
	assert_int_equal(f->trigger_seq, seq);
	assert_int_equal(f->width, 32);
	assert_int_equal(f->height, 24);
	assert_true(f->stride >= 3 * f->width);
	for (uint32_t y = 0; y < f->height; y += 7)
		for (uint32_t x = 0; x < f->width; x += 5)
			for (uint32_t c = 0; c < 3; c++)
				assert_int_equal(f->data[y * f->stride + x * 3 + c], fscan_camera_fake_pixel(cam, seq, x, y, c));
}

static void test_two_triggers_grouped(void **state)
{
	struct fscan_camera *cam = *state;
	assert_int_equal(fscan_camera_count(cam), 4);
	assert_int_equal(fscan_camera_arm(cam, 10, 2), 0);
	for (uint32_t t = 0; t < 2; t++) {
		struct fscan_frame_set *set = NULL;
		assert_int_equal(fscan_camera_collect(cam, 1000, &set), 0);
		assert_int_equal(set->trigger_seq, 10 + t);
		assert_int_equal(set->count, 4);
		assert_true(set->skew_ns <= 2000000u);
		for (uint32_t c = 0; c < 4; c++)
			check_pixels(&set->frames[c], c, 10 + t);
		fscan_frame_set_free(set);
	}
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(cam, 10, &set), -ENODATA);
	assert_null(set);
}

static void test_info(void **state)
{
	struct fscan_camera_info info;
	assert_int_equal(fscan_camera_info(*state, 2, &info), 0);
	assert_string_equal(info.id, "fake:2");
	assert_int_equal(info.width, 32);
	assert_int_equal(fscan_camera_info(*state, 4, &info), -EINVAL);
}

static void expect_fault(struct fscan_camera *cam, enum fscan_camera_fake_fault fault, uint32_t bad_cam,
			 uint32_t trigger_index, int want)
{
	assert_int_equal(fscan_camera_fake_inject(cam, bad_cam, trigger_index, fault), 0);
	assert_int_equal(fscan_camera_arm(cam, 0, 2), 0);
	struct fscan_frame_set *set = NULL;
	int r = 0;
	for (uint32_t t = 0; t <= trigger_index && r == 0; t++) {
		r = fscan_camera_collect(cam, 100, &set);
		if (r == 0) {
			fscan_frame_set_free(set);
			set = NULL;
		}
	}
	assert_int_equal(r, want);
	assert_null(set);
	for (uint32_t c = 0; c < 4; c++)
		assert_int_equal(fscan_camera_frame_status(cam, c), c == bad_cam ? want : 0);
	/* The arm is abandoned; a fresh arm works again. */
	assert_int_equal(fscan_camera_collect(cam, 10, &set), -ENODATA);
	assert_int_equal(fscan_camera_arm(cam, 2, 1), 0);
	assert_int_equal(fscan_camera_collect(cam, 100, &set), 0);
	fscan_frame_set_free(set);
}

static void test_timeout(void **state)
{
	expect_fault(*state, FSCAN_CAMERA_FAKE_TIMEOUT, 1, 0, -ETIMEDOUT);
}

static void test_timeout_on_second_trigger(void **state)
{
	expect_fault(*state, FSCAN_CAMERA_FAKE_TIMEOUT, 3, 1, -ETIMEDOUT);
}

static void test_dropped(void **state)
{
	expect_fault(*state, FSCAN_CAMERA_FAKE_DROPPED, 2, 0, -EIO);
}

static void test_wrong_trigger(void **state)
{
	expect_fault(*state, FSCAN_CAMERA_FAKE_WRONG_TRIGGER, 0, 0, -EXDEV);
}

static void test_wrong_trigger_on_last(void **state)
{
	expect_fault(*state, FSCAN_CAMERA_FAKE_WRONG_TRIGGER, 2, 1, -EXDEV);
}

static void test_late_timestamp(void **state)
{
	expect_fault(*state, FSCAN_CAMERA_FAKE_LATE, 3, 0, -EXDEV);
}

struct firer {
	struct fscan_camera *cam;
	int fired;
};

static void *fire_later(void *arg)
{
	struct firer *f = arg;
	struct timespec ts = {0, 20 * 1000000L};
	nanosleep(&ts, NULL);
	f->fired = fscan_camera_fake_fire(f->cam);
	return NULL;
}

static void test_frames_only_after_trigger(void **state)
{
	struct fscan_camera *cam = *state;
	assert_int_equal(fscan_camera_fake_set_manual(cam, true), 0);
	assert_int_equal(fscan_camera_arm(cam, 5, 1), 0);
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(cam, 30, &set), -ETIMEDOUT);
	/* That abandoned the arm: arm again, and fire from another thread meanwhile. */
	assert_int_equal(fscan_camera_arm(cam, 5, 1), 0);
	struct firer f = {.cam = cam};
	pthread_t th;
	assert_int_equal(pthread_create(&th, NULL, fire_later, &f), 0);
	int r = fscan_camera_collect(cam, 2000, &set);
	pthread_join(th, NULL);
	assert_int_equal(f.fired, 0);
	assert_int_equal(r, 0);
	check_pixels(&set->frames[1], 1, 5);
	fscan_frame_set_free(set);
	assert_int_equal(fscan_camera_fake_arm_count(cam), 2);
}

static void test_state_errors(void **state)
{
	struct fscan_camera *cam = *state;
	struct fscan_frame_set *set = NULL;
	assert_int_equal(fscan_camera_collect(cam, 0, &set), -ENODATA);
	assert_int_equal(fscan_camera_arm(cam, 0, 0), -EINVAL);
	assert_int_equal(fscan_camera_arm(cam, 0, 17), -EINVAL);
	assert_int_equal(fscan_camera_arm(cam, 0, 1), 0);
	assert_int_equal(fscan_camera_arm(cam, 0, 1), -EBUSY);
	struct fscan_camera_config cfg = {0};
	assert_int_equal(fscan_camera_configure(cam, &cfg), -EBUSY);
	assert_int_equal(fscan_camera_disarm(cam), 0);
	assert_int_equal(fscan_camera_configure(cam, &cfg), 0);
	cfg.analogue_gain = 100.0f;
	assert_int_equal(fscan_camera_configure(cam, &cfg), -EINVAL);
	assert_int_equal(fscan_camera_fake_inject(cam, 9, 0, FSCAN_CAMERA_FAKE_TIMEOUT), -EINVAL);
}

static void test_create_errors(void **state)
{
	(void)state;
	struct fscan_camera *cam = NULL;
	struct fscan_camera_params p = {.count = FSCAN_CAMERA_MAX + 1};
	assert_int_equal(fscan_camera_create(&fscan_camera_fake_ops, &p, &cam), -EINVAL);
	assert_null(cam);
	assert_int_equal(fscan_camera_create(NULL, &p, &cam), -EINVAL);
	/* Defaults: 4 cameras of 64 x 48. */
	assert_int_equal(fscan_camera_create(&fscan_camera_fake_ops, NULL, &cam), 0);
	assert_int_equal(fscan_camera_count(cam), 4);
	struct fscan_camera_info info;
	assert_int_equal(fscan_camera_info(cam, 0, &info), 0);
	assert_int_equal(info.width, 64);
	assert_int_equal(info.height, 48);
	fscan_camera_destroy(cam);
	fscan_camera_destroy(NULL);
	fscan_frame_set_free(NULL);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test_setup_teardown(test_two_triggers_grouped, setup, teardown),
		cmocka_unit_test_setup_teardown(test_info, setup, teardown),
		cmocka_unit_test_setup_teardown(test_timeout, setup, teardown),
		cmocka_unit_test_setup_teardown(test_timeout_on_second_trigger, setup, teardown),
		cmocka_unit_test_setup_teardown(test_dropped, setup, teardown),
		cmocka_unit_test_setup_teardown(test_wrong_trigger, setup, teardown),
		cmocka_unit_test_setup_teardown(test_wrong_trigger_on_last, setup, teardown),
		cmocka_unit_test_setup_teardown(test_late_timestamp, setup, teardown),
		cmocka_unit_test_setup_teardown(test_frames_only_after_trigger, setup, teardown),
		cmocka_unit_test_setup_teardown(test_state_errors, setup, teardown),
		cmocka_unit_test(test_create_errors),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
