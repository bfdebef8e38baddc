// The rig file: the committed default equals the built-in rig, the geometry is what the issue
// asks for, and malformed files are refused with a message naming the key.
#include "sim/sim.hpp"

#include <cmath>
#include <cstdarg>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <setjmp.h>
#include <string>
#include <unistd.h>

extern "C" {
#include <cmocka.h>
}

using namespace facescan;
using namespace facescan::sim;

static std::string write_temp(const std::string &text)
{
	char path[] = "/tmp/facescan-rig-XXXXXX";
	int fd = mkstemp(path);
	assert_true(fd >= 0);
	assert_int_equal(write(fd, text.data(), text.size()), (ssize_t)text.size());
	close(fd);
	return path;
}

static void expect_error(const std::string &text, const char *needle)
{
	std::string path = write_temp(text);
	Rig rig;
	Status st = load_rig(path, &rig);
	unlink(path.c_str());
	std::printf("  %s -> %s\n", needle, st.message().c_str());
	assert_int_equal(st.code(), -EINVAL);
	assert_non_null(std::strstr(st.message().c_str(), needle));
	assert_non_null(std::strstr(st.message().c_str(), path.c_str()));
}

static void test_default_file_matches_builtin(void **)
{
	Rig file, builtin = default_rig();
	Status st = load_rig("tools/sim/rigs/default.yaml", &file);
	assert_true(st.ok());
	assert_int_equal(file.cameras.size(), builtin.cameras.size());
	assert_int_equal(file.projectors.size(), builtin.projectors.size());
	for (size_t i = 0; i < file.cameras.size(); i++) {
		const CameraModel &a = file.cameras[i].model, &b = builtin.cameras[i].model;
		assert_true(cv::norm(a.K - b.K) < 1e-12 && cv::norm(a.R - b.R) < 1e-12);
		assert_true(cv::norm(a.T - b.T) < 1e-9 && cv::norm(a.dist - b.dist) < 1e-12);
		assert_true(a.size == b.size);
	}
	for (size_t i = 0; i < file.projectors.size(); i++)
		assert_true(cv::norm(file.projectors[i].centre() - builtin.projectors[i].centre()) < 1e-9);
	assert_true(cv::norm(file.sensor.crosstalk - builtin.sensor.crosstalk) < 1e-12);
	assert_int_equal(file.lighting.lights.size(), builtin.lighting.lights.size());
}

static void test_default_geometry(void **)
{
	Rig rig = default_rig();
	assert_int_equal(rig.cameras.size(), 4);
	assert_int_equal(rig.projectors.size(), 3);
	const double want_az[4] = {-60, -20, 20, 60};
	for (size_t i = 0; i < 4; i++) {
		const CameraModel &c = rig.cameras[i].model;
		assert_int_equal(c.size.width, 1600);
		assert_int_equal(c.size.height, 1200);
		cv::Vec3d rel = c.centre() - cv::Vec3d(0, -10, 40);
		double az = std::atan2(rel[0], rel[2]) * 180 / M_PI;
		std::printf("  cam%zu azimuth %.2f distance %.1f\n", i, az, cv::norm(rel));
		assert_true(std::fabs(az - want_az[i]) < 1e-6);
		assert_true(std::fabs(cv::norm(rel) - 550) < 1e-6);
		// The target projects near the principal point: the camera looks at the head.
		cv::Vec3d x = c.R * cv::Vec3d(0, -10, 40) + c.T;
		assert_true(x[2] > 500 && std::fabs(x[0] / x[2]) < 1e-9 && std::fabs(x[1] / x[2]) < 1e-9);
	}
	for (size_t i = 0; i < 3; i++) {
		assert_int_equal(rig.projectors[i].size.width, 1024);
		assert_true(rig.projectors[i].centre()[1] > rig.cameras[0].model.centre()[1] + 50);
	}
}

static void test_scale(void **)
{
	Rig rig = default_rig();
	CameraModel before = rig.cameras[1].model;
	assert_true(scale_rig(0.5, &rig).ok());
	const CameraModel &c = rig.cameras[1].model;
	assert_int_equal(c.size.width, 800);
	assert_int_equal(c.size.height, 600);
	// A world point lands at half the (pixel-centre) coordinates.
	cv::Vec3d p = before.R * cv::Vec3d(20, 30, 50) + before.T;
	double u0 = before.K(0, 0) * p[0] / p[2] + before.K(0, 2);
	double u1 = c.K(0, 0) * p[0] / p[2] + c.K(0, 2);
	assert_true(std::fabs((u0 + 0.5) * 0.5 - (u1 + 0.5)) < 1e-9);
	assert_int_equal(scale_rig(0, &rig).code(), -EINVAL);
	assert_int_equal(scale_rig(0.001, &rig).code(), -EINVAL);
}

static void test_missing_file(void **)
{
	Rig rig;
	Status st = load_rig("/nonexistent/rig.yaml", &rig);
	assert_int_equal(st.code(), -ENOENT);
	assert_non_null(std::strstr(st.message().c_str(), "/nonexistent/rig.yaml"));
}

static const char *kCam = "{ azimuth_deg: 10, size: [ 640, 480 ], focal_px: [ 800, 800 ] }";

static void test_partial_file_uses_defaults(void **)
{
	std::string path = write_temp(std::string("cameras:\n  - ") + kCam + "\n");
	Rig rig;
	Status st = load_rig(path, &rig);
	unlink(path.c_str());
	assert_true(st.ok());
	assert_int_equal(rig.cameras.size(), 1);
	assert_int_equal(rig.cameras[0].model.size.width, 640);
	assert_true(std::fabs(rig.cameras[0].model.K(0, 2) - 319.5) < 1e-12);
	assert_int_equal(rig.projectors.size(), 3); // from the default rig
}

static void test_errors(void **)
{
	expect_error("cameras:\n  - { azimuth_deg: 10, size: [ 640, 480 ], focal_px: [ 800, 800 ], "
		     "colour: 3 }\n",
		     "cameras[0].colour: unknown key");
	expect_error("cameras:\n  - { azimuth_deg: 10, size: [ 640 ], focal_px: [ 800, 800 ] }\n",
		     "cameras[0].size");
	expect_error("cameras:\n  - { azimuth_deg: 10, size: [ 640, 480 ] }\n", "cameras[0].focal_px: missing");
	expect_error("cameras:\n  - { size: [ 640, 480 ], focal_px: [ 800, 800 ] }\n",
		     "cameras[0].azimuth_deg: missing");
	expect_error("cameras:\n  - { azimuth_deg: 10, size: [ 640, 480 ], focal_px: [ 800, 800 ], "
		     "dist: [ 0.1, 0 ] }\n",
		     "cameras[0].dist");
	expect_error("cameras:\n  - { azimuth_deg: 10, size: [ 640, 480 ], focal_px: [ -5, 800 ] }\n",
		     "cameras[0].focal_px: must be positive");
	expect_error("cameras:\n  - { R: [ 1, 0, 0, 0, 1, 0, 0, 0, 1 ], size: [ 640, 480 ], "
		     "focal_px: [ 800, 800 ] }\n",
		     "R and T must be given together");
	expect_error("cameras:\n  - { R: [ 2, 0, 0, 0, 1, 0, 0, 0, 1 ], T: [ 0, 0, 0 ], "
		     "size: [ 640, 480 ], focal_px: [ 800, 800 ] }\n",
		     "not a rotation matrix");
	expect_error("cameras: []\n", "cameras: expected a non-empty list");
	expect_error("sensor:\n  adc_bits: 40\n", "sensor.adc_bits");
	expect_error("sensor:\n  full_well_e: many\n", "sensor.full_well_e: expected a number");
	expect_error("lighting:\n  lights:\n    - { azimuth_deg: 0, brightness: 1 }\n",
		     "lighting.lights[0].brightness: unknown key");
	expect_error("projector:\n  - {}\n", "projector: unknown key");
	expect_error("cameras: [ 1, 2\n", "YAML parse error");
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_default_file_matches_builtin),
		cmocka_unit_test(test_default_geometry),
		cmocka_unit_test(test_scale),
		cmocka_unit_test(test_missing_file),
		cmocka_unit_test(test_partial_file_uses_defaults),
		cmocka_unit_test(test_errors),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
