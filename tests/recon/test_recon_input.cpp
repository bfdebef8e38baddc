// The pipeline refuses bad input with an error naming the camera and the cause: blank (all
// white / all black) frames, a frame without the pattern, frames that do not match the
// calibration, too few cameras.
#include "recon/pipeline.hpp"

#include "cmocka.hpp"
#include "synthetic_rig.hpp"

#include <opencv2/imgproc.hpp>

#include <cstdio>
#include <random>
#include <cstring>

using namespace facescan;

static CaptureSet base_set()
{
	CaptureSet set;
	set.calibration.cameras = synth::ring();
	for (CameraModel &c : set.calibration.cameras) {
		c.size = cv::Size(160, 120);
		c.K = cv::Matx33d(200, 0, 80, 0, 200, 60, 0, 0, 1);
	}
	std::mt19937 rng(5);
	for (size_t i = 0; i < set.calibration.cameras.size(); ++i) {
		cv::Mat f(120, 160, CV_8UC3);
		cv::randu(f, cv::Scalar::all(0), cv::Scalar::all(255)); // noise: no pattern in it
		set.frames.push_back(f);
	}
	set.meta.scan_id = "test";
	return set;
}

static Pattern pattern()
{
	Pattern p;
	assert_true(default_pattern(SlideSpec(), &p).ok());
	return p;
}

static Status run(const CaptureSet &set)
{
	recon::Mesh mesh;
	recon::ReconReport report;
	const Status s = recon::reconstruct(set, pattern(), recon::ReconParams(), &mesh, &report);
	std::printf("-> %d: %s\n", s.code(), s.message().c_str());
	return s;
}

static void test_white_and_black_frames(void **)
{
	CaptureSet set = base_set();
	set.frames[2].setTo(cv::Scalar::all(255));
	Status s = run(set);
	assert_false(s.ok());
	assert_non_null(std::strstr(s.message().c_str(), "camera 2"));
	assert_non_null(std::strstr(s.message().c_str(), "all white"));
	set = base_set();
	set.frames[0].setTo(cv::Scalar::all(0));
	s = run(set);
	assert_false(s.ok());
	assert_non_null(std::strstr(s.message().c_str(), "camera 0"));
	assert_non_null(std::strstr(s.message().c_str(), "all black"));
}

static void test_no_pattern(void **)
{
	const Status s = run(base_set());
	assert_false(s.ok());
	assert_non_null(std::strstr(s.message().c_str(), "no pattern"));
}

static void test_size_mismatch(void **)
{
	CaptureSet set = base_set();
	cv::resize(set.frames[1], set.frames[1], cv::Size(150, 120));
	const Status s = run(set);
	assert_int_equal(s.code(), -EINVAL);
	assert_non_null(std::strstr(s.message().c_str(), "camera 1"));
	assert_non_null(std::strstr(s.message().c_str(), "calibration"));
}

static void test_too_few_cameras_and_frames(void **)
{
	CaptureSet set = base_set();
	set.frames.pop_back();
	assert_int_equal(run(set).code(), -EINVAL);
	set.calibration.cameras.resize(1);
	set.frames.resize(1);
	assert_int_equal(run(set).code(), -EINVAL);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_white_and_black_frames),
		cmocka_unit_test(test_no_pattern),
		cmocka_unit_test(test_size_mismatch),
		cmocka_unit_test(test_too_few_cameras_and_frames),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
