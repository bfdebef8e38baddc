// The simulated camera backend wired to the booth simulator (tools/sim) through
// fscan_sim_booth_render: one arm renders one simulated scan, pattern then texture shot, and
// the last scan can be written as a capture set that host/capture reads back.
#include <cerrno>
#include <cstdarg>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <setjmp.h>
#include <string>

#include "capture/capture_set.hpp"
#include "facescan/camera.h"
#include "sim/booth_camera.h"

// cmocka last: its fail() macro would clash with the C++ library's.
extern "C" {
#include <cmocka.h>
}

namespace {

// Mean absolute difference between two RGB frames, and the spread of one frame's values.
double mean_abs_diff(const fscan_frame &a, const fscan_frame &b)
{
	double sum = 0;
	for (uint32_t y = 0; y < a.height; y++)
		for (uint32_t x = 0; x < a.width * 3; x++)
			sum += std::abs((int)a.data[y * a.stride + x] - (int)b.data[y * b.stride + x]);
	return sum / (a.width * 3.0 * a.height);
}

double stddev(const fscan_frame &f)
{
	double s = 0, s2 = 0, n = (double)f.width * 3 * f.height;
	for (uint32_t y = 0; y < f.height; y++)
		for (uint32_t x = 0; x < f.width * 3; x++) {
			double v = f.data[y * f.stride + x];
			s += v;
			s2 += v * v;
		}
	double m = s / n;
	return std::sqrt(s2 / n - m * m);
}

void test_booth_scan(void **)
{
	fscan_sim_booth_params bp{};
	bp.scale = 0.2;
	bp.seed = 7;
	fscan_sim_booth *booth = nullptr;
	assert_int_equal(fscan_sim_booth_create(&bp, &booth), 0);
	uint32_t count, w, h;
	assert_int_equal(fscan_sim_booth_geometry(booth, &count, &w, &h), 0);
	printf("sim booth: %u cameras, %ux%u\n", count, w, h);
	assert_true(count >= 2 && count <= FSCAN_CAMERA_MAX);
	fscan_camera_params p{};
	assert_int_equal(fscan_sim_booth_camera_params(booth, &p), 0);
	fscan_camera *cam = nullptr;
	assert_int_equal(fscan_camera_create(&fscan_camera_sim_ops, &p, &cam), 0);
	assert_int_equal(fscan_camera_count(cam), (int)count);
	assert_int_equal(fscan_camera_arm(cam, 100, 2), 0);
	fscan_frame_set *pattern = nullptr, *texture = nullptr;
	assert_int_equal(fscan_camera_collect(cam, 1000, &pattern), 0);
	assert_int_equal(fscan_camera_collect(cam, 1000, &texture), 0);
	assert_int_equal(pattern->trigger_seq, 100);
	assert_int_equal(texture->trigger_seq, 101);
	for (uint32_t c = 0; c < count; c++) {
		assert_int_equal(pattern->frames[c].width, w);
		// A lit head is not a flat image, and the texture shot is not the pattern shot.
		double sd = stddev(pattern->frames[c]);
		double diff = mean_abs_diff(pattern->frames[c], texture->frames[c]);
		printf("camera %u: pattern stddev %.1f, |pattern - texture| %.1f\n", c, sd, diff);
		assert_true(sd > 5.0);
		assert_true(diff > 2.0);
	}
	fscan_frame_set_free(pattern);
	fscan_frame_set_free(texture);

	char tmpl[] = "/tmp/fscan-simbooth-XXXXXX";
	std::string dir = mkdtemp(tmpl);
	assert_int_equal(fscan_sim_booth_write_last(booth, dir.c_str()), 0);
	facescan::CaptureSet set;
	facescan::Status st = facescan::read_capture_set(dir, &set);
	assert_true(st.ok());
	assert_int_equal(set.frames.size(), count);
	assert_int_equal(set.frames[0].cols, (int)w);
	// The written set replays through the replay backend.
	fscan_camera_params rp{};
	rp.source = dir.c_str();
	fscan_camera *replay = nullptr;
	assert_int_equal(fscan_camera_create(&fscan_camera_replay_ops, &rp, &replay), 0);
	assert_int_equal(fscan_camera_count(replay), (int)count);
	fscan_camera_destroy(replay);
	assert_int_equal(std::system(("rm -rf '" + dir + "'").c_str()), 0);

	fscan_camera_destroy(cam);
	fscan_sim_booth_destroy(booth);
}

void test_booth_bad_params(void **)
{
	fscan_sim_booth *booth = nullptr;
	fscan_sim_booth_params bp{};
	bp.scene = "no-such-scene";
	assert_int_equal(fscan_sim_booth_create(&bp, &booth), -EINVAL);
	bp.scene = nullptr;
	bp.scale = 5;
	assert_int_equal(fscan_sim_booth_create(&bp, &booth), -EINVAL);
	bp.scale = 0;
	bp.rig_path = "/nonexistent/rig.yaml";
	assert_int_equal(fscan_sim_booth_create(&bp, &booth), -ENOENT);
	assert_null(booth);
	bp.rig_path = nullptr;
	assert_int_equal(fscan_sim_booth_create(&bp, &booth), 0);
	assert_int_equal(fscan_sim_booth_write_last(booth, "/tmp"), -ENODATA);
	fscan_sim_booth_destroy(booth);
	fscan_sim_booth_destroy(nullptr);
}

} // namespace

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_booth_bad_params),
		cmocka_unit_test(test_booth_scan),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
