// DriverCameras over drivers/camera's fake backend: frames converted and stamped with the MCU's
// trigger, and the driver's errors (timeout, dropped frame, frame of another trigger, late
// frame) turned into the daemon's capture failures.
#include "daemon/driver_cameras.hpp"
#include "facescan/camera.h"
#include "facescan/camera_fake.h"

#include <cstring>
#include <string>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

using namespace facescan::daemon;

static TriggerReport report(uint32_t seq)
{
	TriggerReport r;
	r.sequence = seq;
	return r;
}

static void test_frames(void **)
{
	DriverCameras cams("fake", "", 4, 8000, 1000);
	assert_true(cams.open().ok());
	assert_true(cams.prepare().ok());
	Capture c;
	facescan::Status s = cams.collect(report(7), 500, &c);
	if (!s.ok())
		fail_msg("%s", s.message().c_str());
	assert_int_equal(c.frames.size(), 8);
	assert_true(check_capture(c, 4, 1000).ok());
	const Frame &f = c.frames[5]; // camera 1, texture shot (trigger 1 of the arm)
	assert_true(f.texture);
	assert_int_equal(f.camera, 1);
	assert_int_equal(f.trigger, 7u);
	// BGR in the daemon, RGB in the driver
	const cv::Vec3b px = f.image.at<cv::Vec3b>(3, 2);
	assert_int_equal(px[2], fscan_camera_fake_pixel(1, 1, 2, 3, 0));
	assert_int_equal(px[0], fscan_camera_fake_pixel(1, 1, 2, 3, 2));
}

static void expect_fault(enum fscan_camera_fake_fault fault, int code, const char *text)
{
	DriverCameras cams("fake", "", 4, 8000, 1000);
	assert_true(cams.open().ok());
	assert_int_equal(fscan_camera_fake_inject(cams.handle(), 2, 0, fault), 0);
	assert_true(cams.prepare().ok());
	Capture c;
	facescan::Status s = cams.collect(report(1), 200, &c);
	if (s.code() != code || s.message().find(text) == std::string::npos)
		fail_msg("fault %d: want %d '%s', got %d '%s'", fault, code, text, s.code(), s.message().c_str());
	// the next scan works again
	assert_true(cams.prepare().ok());
	assert_true(cams.collect(report(2), 200, &c).ok());
}

static void test_faults(void **)
{
	// The camera named in words, not errno's ("Connection timed out", seen in the soak).
	expect_fault(FSCAN_CAMERA_FAKE_TIMEOUT, -ETIMEDOUT, "no frame within 200 ms (camera 2: no frame)");
	expect_fault(FSCAN_CAMERA_FAKE_DROPPED, -EIO, "(camera 2: failed frame)");
	expect_fault(FSCAN_CAMERA_FAKE_WRONG_TRIGGER, -EPROTO, "frames from different triggers");
	expect_fault(FSCAN_CAMERA_FAKE_LATE, -EPROTO, "too far apart");
	expect_fault(FSCAN_CAMERA_FAKE_DROPPED, -EIO, "camera 2");
}

static void test_missing_replay_source(void **)
{
	DriverCameras cams("replay", "/nonexistent/capture", 4, 8000, 1000);
	facescan::Status s = cams.open();
	assert_false(s.ok());
	DriverCameras sim("simulated", "", 4, 8000, 1000);
	assert_int_equal(sim.open().code(), -ENOTSUP); // no renderer attached
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_frames),
		cmocka_unit_test(test_faults),
		cmocka_unit_test(test_missing_replay_source),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
