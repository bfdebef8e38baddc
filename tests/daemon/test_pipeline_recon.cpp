// The reconstruction library behind the daemon: input errors name their cause (the capture set
// on disk, the booth's calibration file) and leave no output; on a simulated set its accuracy
// figures are the benchmark's.
#include "daemon/pipeline_recon.hpp"
#include "eval/eval.hpp"
#include "mesh_io/mesh_io.hpp"
#include "sim/sim.hpp"
#include "simulated_scan.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
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

// A simulated scan left on disk as the booth's simulated cameras leave it: the daemon scores its
// mesh as `facescan evaluate` and the benchmark do — truth points seen by two cameras and lit by
// a projector of the rig that rendered it — not over points no pattern reached.
// The scan is the default one (default scene, canonical head, seed 1, pattern frames only), as
// recon/test_e2e renders it: taken from this run's cache when that test has left it there
// (tests/simulated_scan.hpp), else rendered and written here.
static void test_accuracy_of_a_simulated_set(void **)
{
	char tmp[] = "/tmp/facescan-pipeline-XXXXXX";
	assert_non_null(mkdtemp(tmp));
	const facescan::sim::Rig rig = facescan::sim::default_rig();
	std::string dir;
	if (facescan::testing::cached_default_scan(&dir)) {
		std::printf("the default scan, as recon/test_e2e rendered it in this run: %s\n", dir.c_str());
	} else {
		facescan::testing::SimulatedScan scan;
		assert_true(facescan::testing::simulate_default_scan(&scan).ok());
		dir = std::string(tmp) + "/set";
		assert_true(facescan::sim::write_simulated_set(dir, scan.set, scan.sim_truth).ok());
	}
	facescan::CaptureSet set;
	assert_true(facescan::read_calibration(dir + "/calibration.yaml", &set.calibration).ok());

	PipelineReconstructor r("", "");
	Capture c;
	c.source_dir = dir;
	ReconOutput out;
	assert_true(r.run(c, &out).ok());
	assert_true(out.quality.contains("accuracy"));
	const double completeness = out.quality["accuracy"]["completeness"].get<double>();

	facescan::recon::Mesh mesh, head;
	std::vector<facescan::CameraModel> lit_by;
	assert_true(facescan::mesh_io::decode_draco(out.drc.data(), out.drc.size(), &mesh).ok());
	assert_true(facescan::eval::read_ground_truth(dir, &head, &lit_by).ok());
	assert_int_equal(lit_by.size(), rig.projectors.size());
	facescan::eval::EvalResult want;
	assert_true(facescan::eval::evaluate(mesh, head, set.calibration.cameras, facescan::sim::projector_models(rig),
					     facescan::eval::EvalParams(), &want).ok());
	std::printf("daemon accuracy on a simulated set: completeness %.1f %% (evaluate: %.1f %%)\n",
		    100 * completeness, 100 * want.completeness);
	// The daemon scores the mesh before Draco's quantisation, this test the decoded file.
	assert_true(std::fabs(completeness - want.completeness) < 0.005);
	assert_true(completeness >= 0.8);
	// The time is accounted for: reading the set, the pipeline's stages, encoding, the check.
	std::vector<std::string> stages;
	for (const auto &st : out.stage_ms)
		stages.push_back(st.first);
	for (const char *want : {"read", "detect", "encode", "accuracy"})
		assert_true(std::find(stages.begin(), stages.end(), want) != stages.end());
	std::system((std::string("rm -rf ") + tmp).c_str());
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_missing_capture_set),
		cmocka_unit_test(test_frames_without_calibration),
		cmocka_unit_test(test_accuracy_of_a_simulated_set),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
