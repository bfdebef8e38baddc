// The reconstruction library behind the daemon: input errors name their cause (the capture set
// on disk, the booth's calibration file) and leave no output.
#include "daemon/pipeline_recon.hpp"

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

static void test_missing_capture_set(void **)
{
	PipelineReconstructor r("/nonexistent/calibration.yaml", "");
	Capture c;
	c.source_dir = "/nonexistent/capture-set";
	ReconOutput out;
	out.vertices = -7;
	facescan::Status s = r.run(c, &out);
	assert_false(s.ok());
	assert_non_null(std::strstr(s.message().c_str(), "/nonexistent/capture-set"));
	assert_int_equal(out.vertices, -7);
}

static void test_frames_without_calibration(void **)
{
	PipelineReconstructor r("/nonexistent/calibration.yaml", "");
	Capture c;
	Frame f;
	f.image = cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3));
	c.frames.push_back(f);
	ReconOutput out;
	facescan::Status s = r.run(c, &out);
	assert_int_equal(s.code(), -ENOENT);
	assert_non_null(std::strstr(s.message().c_str(), "/nonexistent/calibration.yaml"));
	assert_string_equal(r.backend_name().c_str(), "pipeline");
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_missing_capture_set),
		cmocka_unit_test(test_frames_without_calibration),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
