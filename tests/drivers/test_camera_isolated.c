/* The isolated camera backend: the fake backend run in a child process passes the same grouping
 * contract as in-process, and a camera stack that aborts, hangs or fails to open in its child
 * fails the ops promptly while the caller lives on, leaving no child behind. */
#define _GNU_SOURCE
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "facescan/camera.h"
#include "facescan/camera_fake.h"

/* The inner backend for these tests: the fake, with two faults chosen through the configured
 * exposure (configure() runs in the child, so the choice is made in the child's memory). */
enum { CRASH_EXPOSURE_US = 4242, HANG_EXPOSURE_US = 4343 };
static uint32_t child_exposure_us;

static int faulty_configure(void *ctx, const struct fscan_camera_config *cfg)
{
	child_exposure_us = cfg->exposure_us;
	return fscan_camera_fake_ops.configure(ctx, cfg);
}

static int faulty_next_frame(void *ctx, int timeout_ms, struct fscan_camera_raw_frame *ret_frame)
{
	if (child_exposure_us == CRASH_EXPOSURE_US)
		abort(); /* as libcamera 0.0.3 does when a camera vanished mid-stream */
	if (child_exposure_us == HANG_EXPOSURE_US)
		for (;;)
			pause(); /* a driver stuck in an ioctl */
	return fscan_camera_fake_ops.next_frame(ctx, timeout_ms, ret_frame);
}

static int failing_open(const struct fscan_camera_params *p, void **ret_ctx)
{
	(void)p;
	(void)ret_ctx;
	return -ENODEV;
}

static struct fscan_camera_ops faulty_ops;

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* No child left, not even a zombie: every fork was reaped. */
static void assert_no_children(void)
{
	assert_int_equal(waitpid(-1, NULL, WNOHANG), -1);
	assert_int_equal(errno, ECHILD);
}

static struct fscan_camera *open_isolated(uint32_t exposure_us)
{
	struct fscan_camera_params p = {.count = 3, .width = 40, .height = 30, .isolated_inner = &faulty_ops};
	struct fscan_camera *cam = NULL;
	assert_int_equal(fscan_camera_create(&fscan_camera_isolated_ops, &p, &cam), 0);
	struct fscan_camera_config cfg = {.exposure_us = exposure_us, .external_trigger = true};
	assert_int_equal(fscan_camera_configure(cam, &cfg), 0);
	return cam;
}

static void test_frames_through_the_child(void **state)
{
	(void)state;
	struct fscan_camera *cam = open_isolated(5000);
	assert_int_equal(fscan_camera_count(cam), 3);
	struct fscan_camera_info info;
	assert_int_equal(fscan_camera_info(cam, 2, &info), 0);
	assert_string_equal(info.id, "fake:2");
	assert_int_equal(info.width, 40);
	for (int round = 0; round < 2; round++) { /* arm again after a complete arm */
		assert_int_equal(fscan_camera_arm(cam, 7, 2), 0);
		for (uint32_t t = 0; t < 2; t++) {
			struct fscan_frame_set *set = NULL;
			assert_int_equal(fscan_camera_collect(cam, 2000, &set), 0);
			assert_int_equal(set->trigger_seq, 7 + t);
			assert_int_equal(set->count, 3);
			for (uint32_t c = 0; c < 3; c++) {
				const struct fscan_frame *f = &set->frames[c];
				assert_int_equal(f->camera, c);
				assert_int_equal(f->trigger_seq, 7 + t);
				assert_int_equal(f->width, 40);
				assert_int_equal(f->height, 30);
				for (uint32_t y = 0; y < f->height; y += 3)
					for (uint32_t x = 0; x < f->width; x += 7)
						assert_int_equal(f->data[y * f->stride + 3 * x + 1],
								 fscan_camera_fake_pixel(c, 7 + t, x, y, 1));
			}
			fscan_frame_set_free(set);
		}
	}
	/* Arguments are still checked by the common code; the child's answers pass through. */
	assert_int_equal(fscan_camera_arm(cam, 0, 0), -EINVAL);
	assert_int_equal(fscan_camera_info(cam, 3, &info), -EINVAL);
	fscan_camera_destroy(cam);
	assert_no_children();
}

static void test_child_abort_is_an_error(void **state)
{
	(void)state;
	struct fscan_camera *cam = open_isolated(CRASH_EXPOSURE_US);
	assert_int_equal(fscan_camera_arm(cam, 0, 1), 0);
	struct fscan_frame_set *set = NULL;
	double t0 = now_s();
	assert_int_equal(fscan_camera_collect(cam, 3000, &set), -ENODEV);
	assert_null(set);
	assert_true(now_s() - t0 < 2.0); /* found out by the socket, not by the timeout */
	for (uint32_t c = 0; c < 3; c++)
		assert_int_equal(fscan_camera_frame_status(cam, c), -ENODEV);
	/* Gone for good, promptly. */
	t0 = now_s();
	assert_int_equal(fscan_camera_arm(cam, 1, 1), -ENODEV);
	struct fscan_camera_info info;
	assert_int_equal(fscan_camera_info(cam, 0, &info), -ENODEV);
	struct fscan_camera_config cfg = {.exposure_us = 5000};
	assert_int_equal(fscan_camera_configure(cam, &cfg), -ENODEV);
	assert_int_equal(fscan_camera_disarm(cam), 0);
	assert_true(now_s() - t0 < 1.0);
	fscan_camera_destroy(cam);
	assert_no_children();
}

static void test_hung_child_is_killed(void **state)
{
	(void)state;
	struct fscan_camera *cam = open_isolated(HANG_EXPOSURE_US);
	assert_int_equal(fscan_camera_arm(cam, 0, 1), 0);
	struct fscan_frame_set *set = NULL;
	double t0 = now_s();
	int r = fscan_camera_collect(cam, 200, &set);
	double spent = now_s() - t0;
	printf("hung child: collect -> %d after %.2f s\n", r, spent);
	assert_int_equal(r, -ETIMEDOUT);
	assert_true(spent < 10.0); /* its 200 ms plus the backend's grace */
	assert_int_equal(fscan_camera_arm(cam, 1, 1), -ENODEV);
	fscan_camera_destroy(cam);
	assert_no_children();
}

static void test_open_failure_in_the_child(void **state)
{
	(void)state;
	struct fscan_camera_ops ops = fscan_camera_fake_ops;
	ops.open = failing_open;
	struct fscan_camera_params p = {.isolated_inner = &ops};
	struct fscan_camera *cam = NULL;
	assert_int_equal(fscan_camera_create(&fscan_camera_isolated_ops, &p, &cam), -ENODEV);
	assert_null(cam);
	assert_no_children();
}

/* The child keeps none of the caller's descriptors: a pipe's write end the caller closes is
 * closed everywhere (a daemon's lock or socket must not outlive it in a camera process). */
static void test_child_holds_no_descriptors(void **state)
{
	(void)state;
	int fds[2];
	assert_int_equal(pipe(fds), 0);
	struct fscan_camera *cam = open_isolated(5000);
	close(fds[1]);
	char c;
	assert_int_equal(read(fds[0], &c, 1), 0); /* EOF: no other writer */
	close(fds[0]);
	fscan_camera_destroy(cam);
	assert_no_children();
}

int main(void)
{
	faulty_ops = fscan_camera_fake_ops;
	faulty_ops.configure = faulty_configure;
	faulty_ops.next_frame = faulty_next_frame;
	/* A hang anywhere fails this test, not the whole run. */
	alarm(60);
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_frames_through_the_child),
		cmocka_unit_test(test_child_abort_is_an_error),
		cmocka_unit_test(test_hung_child_is_killed),
		cmocka_unit_test(test_open_failure_in_the_child),
		cmocka_unit_test(test_child_holds_no_descriptors),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
