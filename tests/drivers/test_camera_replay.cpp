// Camera driver, replay and simulated backends: a capture set written by host/capture comes
// back through the C interface as RGB frames grouped per trigger; the simulated backend draws
// through an injected render callback (a test double here; the booth simulator in the product).
#include <cerrno>
#include <cstdarg>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <chrono>
#include <cstring>
#include <setjmp.h>
#include <string>
#include <unistd.h>

#include "capture/capture_set.hpp"
#include "facescan/camera.h"

// cmocka last: its fail() macro would clash with the C++ library's.
extern "C" {
#include <cmocka.h>
}

namespace {

std::string make_dir()
{
	char tmpl[] = "/tmp/fscan-replay-XXXXXX";
	char *d = mkdtemp(tmpl);
	assert_non_null(d);
	return d;
}

void rm_rf(const std::string &dir)
{
	std::string cmd = "rm -rf '" + dir + "'";
	assert_int_equal(std::system(cmd.c_str()), 0);
}

// Camera c's pattern frame is BGR (10c, 20c+1, 30c+2) + x; its texture frame adds 100.
cv::Vec3b pixel(int c, int x, bool texture)
{
	int add = texture ? 100 : 0;
	return cv::Vec3b((uchar)(10 * c + x + add), (uchar)(20 * c + 1 + add), (uchar)(30 * c + 2 + add));
}

std::string write_set(int cameras, bool textures, bool timestamps)
{
	facescan::CaptureSet set;
	for (int c = 0; c < cameras; c++) {
		facescan::CameraModel m;
		m.size = cv::Size(8, 6);
		m.K = cv::Matx33d(100, 0, 4, 0, 100, 3, 0, 0, 1);
		m.T = cv::Vec3d(c * 100.0, 0, 500);
		set.calibration.cameras.push_back(m);
		cv::Mat f(6, 8, CV_8UC3), t(6, 8, CV_8UC3);
		for (int y = 0; y < 6; y++)
			for (int x = 0; x < 8; x++) {
				f.at<cv::Vec3b>(y, x) = pixel(c, x, false);
				t.at<cv::Vec3b>(y, x) = pixel(c, x, true);
			}
		set.frames.push_back(f);
		if (textures)
			set.textures.push_back(t);
		if (timestamps)
			set.meta.timestamps_ns.push_back(1e9 + c * 1000.0);
	}
	set.meta.scan_id = "replay-test";
	set.meta.pattern_id = "fs-l3-14x19-s2";
	std::string dir = make_dir();
	facescan::Status st = facescan::write_capture_set(dir, set);
	if (!st.ok())
		fail_msg("write_capture_set: %s", st.message().c_str());
	return dir;
}

void check_rgb(const fscan_frame &f, int c, bool texture)
{
	assert_int_equal(f.width, 8);
	assert_int_equal(f.height, 6);
	for (uint32_t y = 0; y < f.height; y++)
		for (uint32_t x = 0; x < f.width; x++) {
			cv::Vec3b bgr = pixel(c, (int)x, texture);
			const uint8_t *p = f.data + y * f.stride + x * 3;
			assert_int_equal(p[0], bgr[2]); // R
			assert_int_equal(p[1], bgr[1]);
			assert_int_equal(p[2], bgr[0]); // B
		}
}

void test_replay_two_triggers(void **)
{
	std::string dir = write_set(3, true, true);
	fscan_camera_params p{};
	p.source = dir.c_str();
	fscan_camera *cam = nullptr;
	assert_int_equal(fscan_camera_create(&fscan_camera_replay_ops, &p, &cam), 0);
	assert_int_equal(fscan_camera_count(cam), 3);
	struct fscan_camera_info info; // 'struct': C++ also sees the function of that name
	assert_int_equal(fscan_camera_info(cam, 1, &info), 0);
	assert_string_equal(info.id, "replay:cam1");
	assert_int_equal(info.width, 8);
	fscan_camera_config cfg{};
	assert_int_equal(fscan_camera_configure(cam, &cfg), 0);
	cfg.width = 640;
	assert_int_equal(fscan_camera_configure(cam, &cfg), -EINVAL);
	assert_int_equal(fscan_camera_arm(cam, 40, 2), 0);
	for (int t = 0; t < 2; t++) {
		fscan_frame_set *set = nullptr;
		assert_int_equal(fscan_camera_collect(cam, 100, &set), 0);
		assert_int_equal(set->trigger_seq, 40 + t);
		for (int c = 0; c < 3; c++) {
			check_rgb(set->frames[c], c, t == 1);
			// The recorded sensor time, the texture shot 100 ms later.
			assert_int_equal(set->frames[c].timestamp_ns, 1000000000ull + c * 1000ull + t * 100000000ull);
		}
		assert_int_equal(set->skew_ns, 2000);
		fscan_frame_set_free(set);
	}
	// Three shots are more than a capture set holds.
	assert_int_equal(fscan_camera_arm(cam, 0, 3), -ENODATA);
	fscan_camera_destroy(cam);
	rm_rf(dir);
}

void test_replay_without_textures(void **)
{
	std::string dir = write_set(2, false, false);
	fscan_camera_params p{};
	p.source = dir.c_str();
	fscan_camera *cam = nullptr;
	assert_int_equal(fscan_camera_create(&fscan_camera_replay_ops, &p, &cam), 0);
	assert_int_equal(fscan_camera_arm(cam, 0, 2), -ENODATA);
	assert_int_equal(fscan_camera_arm(cam, 0, 1), 0);
	fscan_frame_set *set = nullptr;
	assert_int_equal(fscan_camera_collect(cam, 100, &set), 0);
	check_rgb(set->frames[1], 1, false);
	fscan_frame_set_free(set);
	fscan_camera_destroy(cam);
	rm_rf(dir);
}

void test_replay_bad_sources(void **)
{
	fscan_camera *cam = nullptr;
	fscan_camera_params p{};
	assert_int_equal(fscan_camera_create(&fscan_camera_replay_ops, &p, &cam), -EINVAL);
	p.source = "/nonexistent/capture";
	assert_int_equal(fscan_camera_create(&fscan_camera_replay_ops, &p, &cam), -ENOENT);
	std::string dir = write_set(2, false, false);
	FILE *f = std::fopen((dir + "/calibration.yaml").c_str(), "w");
	std::fputs("%YAML:1.0\ncamera_count: banana\n", f);
	std::fclose(f);
	p.source = dir.c_str();
	assert_int_equal(fscan_camera_create(&fscan_camera_replay_ops, &p, &cam), -EBADMSG);
	assert_null(cam);
	rm_rf(dir);
}

// ---- simulated backend with a render double ----

struct Renderer {
	int calls = 0;
	int fail_camera = -1;
	int late_camera = -1, late_ms = 0; // its frames arrive late_ms after the arm
	int dropped_camera = -1;           // its frames never arrive
};

int render(void *user, uint32_t camera, uint32_t trigger_index, uint8_t *rgb, uint32_t width,
	   uint32_t height, uint32_t stride, uint64_t *ret_timestamp_ns)
{
	Renderer *r = static_cast<Renderer *>(user);
	r->calls++;
	if ((int)camera == r->fail_camera)
		return -EIO;
	for (uint32_t y = 0; y < height; y++)
		std::memset(rgb + y * stride, (int)(camera * 16 + trigger_index), width * 3);
	(void)ret_timestamp_ns; // keep the backend's synthetic time
	if ((int)camera == r->dropped_camera)
		return FSCAN_CAMERA_RENDER_DROPPED;
	return (int)camera == r->late_camera ? r->late_ms : 0;
}

// Four 16 x 12 cameras drawn by `r`.
fscan_camera *open_sim(Renderer *r)
{
	fscan_camera_params p{};
	p.count = 4;
	p.width = 16;
	p.height = 12;
	p.render = render;
	p.render_user = r;
	fscan_camera *cam = nullptr;
	assert_int_equal(fscan_camera_create(&fscan_camera_sim_ops, &p, &cam), 0);
	return cam;
}

void test_sim_renders_each_camera_and_trigger(void **)
{
	Renderer r;
	fscan_camera *cam = open_sim(&r);
	assert_int_equal(fscan_camera_arm(cam, 0, 2), 0);
	assert_int_equal(r.calls, 8);
	for (uint32_t t = 0; t < 2; t++) {
		fscan_frame_set *set = nullptr;
		assert_int_equal(fscan_camera_collect(cam, 100, &set), 0);
		for (uint32_t c = 0; c < 4; c++) {
			assert_int_equal(set->frames[c].width, 16);
			assert_int_equal(set->frames[c].data[5 * set->frames[c].stride + 7], c * 16 + t);
		}
		fscan_frame_set_free(set);
	}
	// A camera the renderer fails on is that camera's failed frame.
	r.fail_camera = 2;
	assert_int_equal(fscan_camera_arm(cam, 2, 1), 0);
	fscan_frame_set *set = nullptr;
	assert_int_equal(fscan_camera_collect(cam, 100, &set), -EIO);
	assert_int_equal(fscan_camera_frame_status(cam, 2), -EIO);
	// The renderer draws at the sensor size only.
	fscan_camera_config cfg{};
	cfg.width = 32;
	assert_int_equal(fscan_camera_configure(cam, &cfg), -EINVAL);
	fscan_camera_destroy(cam);
	// No renderer, no backend.
	fscan_camera_params p{};
	p.count = 4;
	assert_int_equal(fscan_camera_create(&fscan_camera_sim_ops, &p, &cam), -EINVAL);
}

long ms_since(std::chrono::steady_clock::time_point t0)
{
	return (long)std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - t0).count();
}

// The soak's camera faults at the sensor: a late frame arrives late (in time: collected; too
// late: that camera times out) without holding back the other cameras' frames, and a dropped
// frame never arrives.
void test_sim_late_and_dropped_frames(void **)
{
	Renderer r;
	fscan_camera *cam = open_sim(&r);

	r.late_camera = 1;
	r.late_ms = 150;
	auto t0 = std::chrono::steady_clock::now();
	assert_int_equal(fscan_camera_arm(cam, 0, 2), 0);
	for (uint32_t t = 0; t < 2; t++) {
		fscan_frame_set *set = nullptr;
		assert_int_equal(fscan_camera_collect(cam, 1000, &set), 0);
		assert_int_equal(set->frames[1].data[0], 16 + t);
		fscan_frame_set_free(set);
	}
	long ms = ms_since(t0);
	printf("late frames (150 ms) collected after %ld ms\n", ms);
	assert_true(ms >= 140 && ms < 900);

	r.late_ms = 400;
	assert_int_equal(fscan_camera_arm(cam, 2, 1), 0);
	fscan_frame_set *set = nullptr;
	assert_int_equal(fscan_camera_collect(cam, 100, &set), -ETIMEDOUT);
	assert_int_equal(fscan_camera_frame_status(cam, 1), -ETIMEDOUT);
	assert_int_equal(fscan_camera_frame_status(cam, 0), 0);

	r.late_camera = -1;
	r.dropped_camera = 3;
	assert_int_equal(fscan_camera_arm(cam, 3, 2), 0);
	t0 = std::chrono::steady_clock::now();
	assert_int_equal(fscan_camera_collect(cam, 200, &set), -ETIMEDOUT);
	assert_true(ms_since(t0) >= 190);
	assert_int_equal(fscan_camera_frame_status(cam, 3), -ETIMEDOUT);
	assert_int_equal(fscan_camera_frame_status(cam, 2), 0);

	// Back to healthy: the next arm delivers at once.
	r.dropped_camera = -1;
	assert_int_equal(fscan_camera_arm(cam, 5, 1), 0);
	assert_int_equal(fscan_camera_collect(cam, 100, &set), 0);
	fscan_frame_set_free(set);
	fscan_camera_destroy(cam);
}

} // namespace

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_replay_two_triggers),
		cmocka_unit_test(test_replay_without_textures),
		cmocka_unit_test(test_replay_bad_sources),
		cmocka_unit_test(test_sim_renders_each_camera_and_trigger),
		cmocka_unit_test(test_sim_late_and_dropped_frames),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
