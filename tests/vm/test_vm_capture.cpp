// The format path end to end on real frames, inside the VM tier (tests/vm/README.md): two
// triggers (pattern shot, texture shot) from the two vimc cameras through the libcamera backend,
// saved as a capture set on the share with host/capture's writer, read back with its reader:
// every pixel, the sizes, the timestamps and the calibration come back as written.
// Outside the VM (no FACESCAN_VM=1) it skips.
#include "capture/capture_set.hpp"
#include "facescan/camera.h"

#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <unistd.h>

#include "cmocka.hpp" // last: its macros clash with the standard library's headers

namespace {

using namespace facescan;

std::string g_dir;

void test_vimc_capture_round_trip(void **)
{
	fscan_camera *cam = nullptr;
	assert_int_equal(fscan_camera_create(&fscan_camera_libcamera_ops, nullptr, &cam), 0);
	const uint32_t n = static_cast<uint32_t>(fscan_camera_count(cam));
	assert_true(n >= 2);
	fscan_camera_config cfg{};
	cfg.width = 636; // vimc: multiples of 6 (test_vm_camera.c)
	cfg.height = 480;
	cfg.exposure_us = 8000;
	cfg.analogue_gain = 1.0f;
	cfg.max_skew_us = 1000000; // vimc free-runs: no trigger to line the cameras up (README)
	assert_int_equal(fscan_camera_configure(cam, &cfg), 0);
	assert_int_equal(fscan_camera_arm(cam, 0, 2), 0);

	CaptureSet set;
	set.meta.scan_id = "vimc-round-trip";
	// The format's example id: the set is only written and read here, never reconstructed, so
	// the pattern search default_pattern() runs (slow under TCG) is not needed.
	set.meta.pattern_id = "fs-l3-14x19-s2";
	set.calibration.id = "vimc, nominal intrinsics";
	for (uint32_t shot = 0; shot < 2; shot++) {
		fscan_frame_set *fs = nullptr;
		assert_int_equal(fscan_camera_collect(cam, 10000, &fs), 0);
		for (uint32_t c = 0; c < fs->count; c++) {
			const fscan_frame &f = fs->frames[c];
			cv::Mat rgb(static_cast<int>(f.height), static_cast<int>(f.width), CV_8UC3, f.data, f.stride);
			cv::Mat bgr;
			cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
			(shot == 0 ? set.frames : set.textures).push_back(bgr);
			if (shot == 0) {
				set.meta.timestamps_ns.push_back(static_cast<double>(f.timestamp_ns));
				set.meta.exposure_us.push_back(cfg.exposure_us);
				CameraModel m;
				m.K = cv::Matx33d(800, 0, f.width / 2.0, 0, 800, f.height / 2.0, 0, 0, 1);
				m.T = cv::Vec3d(-100.0 * c, 0, 0);
				m.size = cv::Size(static_cast<int>(f.width), static_cast<int>(f.height));
				set.calibration.cameras.push_back(m);
			}
		}
		fscan_frame_set_free(fs);
	}
	fscan_camera_destroy(cam);

	Status s = write_capture_set(g_dir, set);
	if (!s.ok())
		std::printf("write: %s\n", s.message().c_str());
	assert_true(s.ok());
	CaptureSet back;
	s = read_capture_set(g_dir, &back);
	if (!s.ok())
		std::printf("read: %s\n", s.message().c_str());
	assert_true(s.ok());
	assert_int_equal(back.frames.size(), n);
	assert_int_equal(back.textures.size(), n);
	assert_int_equal(back.calibration.cameras.size(), n);
	assert_string_equal(back.meta.scan_id.c_str(), set.meta.scan_id.c_str());
	assert_string_equal(back.meta.pattern_id.c_str(), set.meta.pattern_id.c_str());
	assert_int_equal(back.meta.timestamps_ns.size(), n);
	for (uint32_t c = 0; c < n; c++) {
		assert_true(back.frames[c].size() == set.frames[c].size());
		assert_int_equal(cv::norm(back.frames[c], set.frames[c], cv::NORM_INF), 0);
		assert_int_equal(cv::norm(back.textures[c], set.textures[c], cv::NORM_INF), 0);
		assert_true(back.meta.timestamps_ns[c] == set.meta.timestamps_ns[c]);
		assert_true(back.calibration.cameras[c].size == set.calibration.cameras[c].size);
		assert_true(cv::norm(back.calibration.cameras[c].T - set.calibration.cameras[c].T) < 1e-9);
	}
	std::printf("capture set %s: %u cameras, %dx%d, written and read back identical\n", g_dir.c_str(), n,
		    back.frames[0].cols, back.frames[0].rows);
}

} // namespace

int main()
{
	const char *vm = std::getenv("FACESCAN_VM");
	const char *share = std::getenv("FACESCAN_VM_SHARE");
	if (!vm || !share) {
		std::fprintf(stderr, "test_vm_capture: skipped: runs inside the VM tier (tests/vm/test_vm.sh), "
				     "where vimc gives libcamera two cameras\n");
		return 77;
	}
	alarm(120);
	g_dir = std::string(share) + "/capture-round-trip";
	const CMUnitTest tests[] = {
		cmocka_unit_test(test_vimc_capture_round_trip),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
