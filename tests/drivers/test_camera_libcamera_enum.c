/* libcamera backend, the part that runs on any machine: enumeration. Where no camera exists
 * (this build host: no /dev/video*, see docs/drivers.md) create() must fail cleanly with
 * -ENODEV — no crash, no leak, no log on stderr; where cameras exist it must open them. */
#include <errno.h>
#include <glob.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <cmocka.h>

#include "facescan/camera.h"

static size_t video_nodes(void)
{
	glob_t g;
	size_t n = 0;
	if (glob("/dev/video*", 0, NULL, &g) == 0)
		n = g.gl_pathc;
	globfree(&g);
	return n;
}

static void test_enumerate(void **state)
{
	(void)state;
	struct fscan_camera *cam = NULL;
	int r = fscan_camera_create(&fscan_camera_libcamera_ops, NULL, &cam);
	printf("libcamera: create -> %d, %zu /dev/video nodes\n", r, video_nodes());
	if (video_nodes() == 0) {
		assert_int_equal(r, -ENODEV);
		assert_null(cam);
		return;
	}
	/* Video nodes need not be cameras libcamera supports (codecs, loopbacks). */
	assert_true(r == 0 || r == -ENODEV);
	if (r == 0) {
		assert_true(fscan_camera_count(cam) >= 1);
		struct fscan_camera_info info;
		assert_int_equal(fscan_camera_info(cam, 0, &info), 0);
		assert_true(info.id[0] != '\0');
	}
	fscan_camera_destroy(cam);
}

static void test_unknown_id_is_enodev(void **state)
{
	(void)state;
	struct fscan_camera *cam = NULL;
	struct fscan_camera_params p = {.source = "/base/no/such/camera@0"};
	assert_int_equal(fscan_camera_create(&fscan_camera_libcamera_ops, &p, &cam), -ENODEV);
	assert_null(cam);
}

static void test_twice(void **state)
{
	/* The camera manager is started and stopped cleanly: a second open behaves the same. */
	(void)state;
	struct fscan_camera *a = NULL, *b = NULL;
	int ra = fscan_camera_create(&fscan_camera_libcamera_ops, NULL, &a);
	fscan_camera_destroy(a);
	int rb = fscan_camera_create(&fscan_camera_libcamera_ops, NULL, &b);
	fscan_camera_destroy(b);
	assert_int_equal(ra, rb);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_enumerate),
		cmocka_unit_test(test_unknown_id_is_enodev),
		cmocka_unit_test(test_twice),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
