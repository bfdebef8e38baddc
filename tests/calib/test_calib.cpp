// Calibration end to end: the simulator's default rig (4 cameras, 1600x1200) sees a rendered
// chessboard in 14 poses; `facescan calibrate` and the library recover the cameras. Checked
// against the rig's truth in a common frame: focal lengths within 0.5 %, camera centres within
// 0.5 mm, rotations within 0.05 degrees; a face reconstructed with the recovered calibration
// stays within the reconstruction floor. Bad inputs fail with a message and write nothing.
#include "calib/calib.hpp"
#include "capture/capture_set.hpp"
#include "eval/eval.hpp"
#include "recon/pipeline.hpp"
#include "sim/board.hpp"
#include "sim/sim.hpp"

#include "../cmocka.hpp"
#include "../simulated_scan.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace facescan::cli {
int calibrate_main(int argc, char **argv);
}

using namespace facescan;
namespace fs = std::filesystem;

namespace {

constexpr double kMaxViewAngleDeg = 80; // steeper views show no usable board: not rendered

struct Fixture {
	Calibration truth;
	calib::BoardSpec board;
	std::vector<sim::BoardPose> poses;
	std::string dir;				  // pose<k>_cam<i>.png
	std::vector<std::vector<calib::BoardView>> views; // [pose][camera]
	// char, not bool: the setup's threads write neighbouring flags, and vector<bool> packs them
	// into one word (a data race that drops views).
	std::vector<std::vector<char>> rendered;
	// calibrate_rig on all views with the default parameters: the same call for
	// test_rig_accuracy and test_recon_with_recovered_calibration, made once (recovered()).
	bool have_recovered = false;
	Status recovered_status;
	Calibration recovered;
	calib::RigReport recovered_report;
};

Fixture *fx;

double view_angle(const CameraModel &cam, const sim::BoardPose &pose)
{
	const cv::Vec3d n = pose.R * cv::Vec3d(0, 0, 1), d = pose.t - cam.centre();
	return std::acos(n.dot(d) / cv::norm(d)) * 180 / CV_PI;
}

int setup(void **)
{
	fx = new Fixture;
	sim::Rig rig = sim::default_rig();
	fx->truth = sim::rig_calibration(rig);
	fx->board.cols = 9;
	fx->board.rows = 6;
	fx->board.square_mm = 25;
	fx->poses = sim::calibration_poses(fx->truth, fx->board, cv::Vec3d(0, -10, 40), 2);
	char tmpl[] = "/tmp/facescan-calib-XXXXXX";
	if (!mkdtemp(tmpl))
		return -1;
	fx->dir = tmpl;
	const size_t P = fx->poses.size(), C = fx->truth.cameras.size();
	fx->views.assign(P, std::vector<calib::BoardView>(C));
	fx->rendered.assign(P, std::vector<char>(C, 0));
	std::vector<sim::BoardCamera> cams;
	for (const CameraModel &c : fx->truth.cameras)
		cams.emplace_back(c, 1);
	std::atomic<int> failures{0};
	std::atomic<long> render_us{0}, detect_us{0};
	cv::parallel_for_(cv::Range(0, int(P * C)), [&](const cv::Range &r) {
		for (int k = r.start; k < r.end; k++) {
			const size_t p = size_t(k) / C, c = size_t(k) % C;
			const CameraModel &cam = fx->truth.cameras[c];
			cv::Mat img;
			const int64 t0 = cv::getTickCount();
			if (view_angle(cam, fx->poses[p]) > kMaxViewAngleDeg) {
				// The board's edge or back: an empty view, which calibrate must skip.
				img = cv::Mat(cam.size, CV_8U, cv::Scalar(90));
			} else {
				sim::BoardRenderParams rp;
				rp.blur_sigma_px = rig.cameras[c].blur_px;
				rp.seed = uint32_t(k + 1);
				if (!cams[c].render(fx->board, fx->poses[p], rp, &img).ok()) {
					failures++;
					continue;
				}
				fx->rendered[p][c] = 1;
			}
			const std::string path = fx->dir + "/pose" + std::to_string(p) + "_cam" +
						 std::to_string(c) + ".png";
			if (!cv::imwrite(path, img, {cv::IMWRITE_PNG_COMPRESSION, 1}))
				failures++;
			const int64 t1 = cv::getTickCount();
			if (fx->rendered[p][c])
				fx->views[p][c] = calib::detect_board(img, fx->board);
			render_us += long((t1 - t0) * 1e6 / cv::getTickFrequency());
			detect_us += long((cv::getTickCount() - t1) * 1e6 / cv::getTickFrequency());
		}
	});
	std::printf("setup: render+write %.1f s, detect %.1f s (summed over threads)\n",
		    double(render_us) * 1e-6, double(detect_us) * 1e-6);
	return failures ? -1 : 0;
}

std::vector<cv::Size> camera_sizes()
{
	std::vector<cv::Size> sizes;
	for (const CameraModel &c : fx->truth.cameras)
		sizes.push_back(c.size);
	return sizes;
}

// calibrate_rig(all views, default parameters), computed by the first test that asks.
const Status &recovered()
{
	if (!fx->have_recovered) {
		const int64 t0 = cv::getTickCount();
		fx->recovered_status = calib::calibrate_rig(fx->views, camera_sizes(), calib::CalibParams(),
							    &fx->recovered, &fx->recovered_report);
		fx->have_recovered = true;
		std::printf("  calibrate_rig (made once, for every test that needs it): %.1f s\n",
			    double(cv::getTickCount() - t0) / cv::getTickFrequency());
	}
	return fx->recovered_status;
}

int teardown(void **)
{
	std::error_code ec;
	fs::remove_all(fx->dir, ec);
	delete fx;
	return 0;
}

// Runs `facescan calibrate` with the given arguments.
int run_cli(std::vector<std::string> args)
{
	args.insert(args.begin(), "calibrate");
	std::vector<char *> argv;
	for (std::string &a : args)
		argv.push_back(a.data());
	argv.push_back(nullptr);
	std::fflush(stdout);
	return cli::calibrate_main(int(args.size()), argv.data());
}

struct Errors {
	double focal_pct = 0, centre_mm = 0, rotation_deg = 0;
};

// Compares `got` with `want` (both already in the same world frame), camera by camera.
Errors compare(const Calibration &got, const std::vector<CameraModel> &want)
{
	Errors e;
	assert_int_equal(got.cameras.size(), want.size());
	for (size_t i = 0; i < want.size(); i++) {
		const CameraModel &g = got.cameras[i], &w = want[i];
		assert_true(g.size == w.size);
		const double fx_err = 100 * std::abs(g.K(0, 0) / w.K(0, 0) - 1);
		const double fy_err = 100 * std::abs(g.K(1, 1) / w.K(1, 1) - 1);
		const double centre = cv::norm(g.centre() - w.centre());
		cv::Vec3d r;
		cv::Rodrigues(g.R * w.R.t(), r);
		const double rot = cv::norm(r) * 180 / CV_PI;
		std::printf("  camera %zu: fx %+.3f %% fy %+.3f %%, centre %.3f mm, rotation %.4f deg\n",
			    i, 100 * (g.K(0, 0) / w.K(0, 0) - 1), 100 * (g.K(1, 1) / w.K(1, 1) - 1),
			    centre, rot);
		e.focal_pct = std::max({e.focal_pct, fx_err, fy_err});
		e.centre_mm = std::max(e.centre_mm, centre);
		e.rotation_deg = std::max(e.rotation_deg, rot);
	}
	return e;
}

void assert_within_issue_tolerance(const Errors &e)
{
	std::printf("  worst: focal %.3f %%, centre %.3f mm, rotation %.4f deg\n", e.focal_pct,
		    e.centre_mm, e.rotation_deg);
	assert_true(e.focal_pct < 0.5);
	assert_true(e.centre_mm < 0.5);
	assert_true(e.rotation_deg < 0.05);
}

// The truth's cameras re-expressed in camera `ref`'s frame (as calibrate reports them).
std::vector<CameraModel> truth_in_camera_frame(const std::vector<CameraModel> &cams, size_t ref)
{
	std::vector<CameraModel> out;
	const CameraModel &r = cams[ref];
	for (const CameraModel &c : cams) {
		CameraModel m = c;
		m.R = c.R * r.R.t();
		m.T = c.T - m.R * r.T;
		out.push_back(m);
	}
	return out;
}

bool exists(const std::string &path)
{
	std::error_code ec;
	return fs::exists(path, ec);
}

} // namespace

static void test_board_description(void **)
{
	int cols = 0, rows = 0;
	assert_true(calib::parse_board_size("9x6", &cols, &rows).ok());
	assert_int_equal(cols, 9);
	assert_int_equal(rows, 6);
	assert_false(calib::parse_board_size("9x", &cols, &rows).ok());
	assert_false(calib::parse_board_size("9*6", &cols, &rows).ok());
	assert_false(calib::parse_board_size("1x6", &cols, &rows).ok());
	calib::BoardSpec b;
	b.cols = 8;
	b.rows = 6; // looks the same after a half turn
	Status st = calib::validate_board(b);
	std::printf("  8x6: %s\n", st.message().c_str());
	assert_int_equal(st.code(), -EINVAL);
	b.type = calib::TargetType::Charuco; // ids make any ChArUco size unambiguous
	b.marker_mm = 18;
	assert_true(calib::validate_board(b).ok());
	b.marker_mm = 30;
	assert_false(calib::validate_board(b).ok());
	int dict = -1;
	assert_true(calib::parse_dictionary("DICT_4X4_50", &dict).ok());
	assert_int_equal(dict, 0);
	assert_false(calib::parse_dictionary("DICT_9X9_1", &dict).ok());
	const std::vector<cv::Point3f> obj = calib::board_object_points(fx->board);
	assert_int_equal(obj.size(), 54);
	assert_true(obj[10] == cv::Point3f(25, 25, 0));
}

// Whatever way up the board is held, corner 0 is the same physical corner.
static void test_corner_order(void **)
{
	const CameraModel &cam = fx->truth.cameras[1];
	sim::BoardCamera bc(cam, 1);
	for (double roll : {0.0, 90.0, 180.0, 270.0}) {
		sim::BoardPose pose = fx->poses[4];
		const cv::Vec3d centre(4 * 25, 2.5 * 25, 0);
		cv::Matx33d Rz;
		cv::Rodrigues(cv::Vec3d(0, 0, roll * CV_PI / 180), Rz);
		const cv::Vec3d world_centre = pose.R * centre + pose.t;
		pose.R = pose.R * Rz;
		pose.t = world_centre - pose.R * centre;
		cv::Mat img;
		assert_true(bc.render(fx->board, pose, sim::BoardRenderParams(), &img).ok());
		const calib::BoardView v = calib::detect_board(img, fx->board);
		assert_true(v.found);
		std::vector<cv::Point3d> world;
		for (const cv::Point3f &o : v.object_points)
			world.push_back(cv::Vec3d(pose.R * cv::Vec3d(o.x, o.y, o.z) + pose.t));
		cv::Vec3d rv;
		cv::Rodrigues(cam.R, rv);
		std::vector<cv::Point2d> want;
		cv::projectPoints(world, rv, cam.T, cam.K, cam.dist, want);
		double worst = 0;
		for (size_t i = 0; i < want.size(); i++)
			worst = std::max(worst, cv::norm(cv::Point2d(v.image_points[i]) - want[i]));
		std::printf("  roll %3.0f deg: worst corner %.3f px from the truth\n", roll, worst);
		assert_true(worst < 0.3);
	}
	const calib::BoardView none = calib::detect_board(cv::Mat(600, 800, CV_8U, cv::Scalar(90)), fx->board);
	assert_false(none.found);
	assert_true(none.reason.find("not found") != std::string::npos);
}

// ChArUco: rendered through a half-size camera, partly out of view; the corners found carry
// their ids and sit where the truth projects them.
static void test_charuco_detection(void **)
{
	sim::Rig rig = sim::default_rig();
	assert_true(sim::scale_rig(0.5, &rig).ok());
	const CameraModel cam = sim::rig_calibration(rig).cameras[1];
	calib::BoardSpec b;
	b.type = calib::TargetType::Charuco;
	b.cols = 9;
	b.rows = 6;
	b.square_mm = 25;
	b.marker_mm = 19;
	const sim::BoardCamera bc(cam, 3);
	for (double shift : {0.0, 120.0}) { // the second pose hangs off the image's right edge
		sim::BoardPose pose = fx->poses[4];
		pose.t += cv::Vec3d(cam.R(0, 0), cam.R(0, 1), cam.R(0, 2)) * shift;
		cv::Mat img;
		assert_true(bc.render(b, pose, sim::BoardRenderParams(), &img).ok());
		const calib::BoardView v = calib::detect_board(img, b);
		std::printf("  shift %.0f mm: %s, %zu corners\n", shift, v.found ? "found" : v.reason.c_str(),
			    v.ids.size());
		assert_true(v.found);
		if (shift == 0)
			assert_int_equal(v.ids.size(), 54);
		else
			assert_true(v.ids.size() >= 8 && v.ids.size() < 54);
		const std::vector<cv::Point3f> all = calib::board_object_points(b);
		std::vector<cv::Point3d> world;
		for (size_t i = 0; i < v.ids.size(); i++) {
			assert_true(v.object_points[i] == all[size_t(v.ids[i])]);
			const cv::Point3f &o = v.object_points[i];
			world.push_back(cv::Vec3d(pose.R * cv::Vec3d(o.x, o.y, o.z) + pose.t));
		}
		cv::Vec3d rv;
		cv::Rodrigues(cam.R, rv);
		std::vector<cv::Point2d> want;
		cv::projectPoints(world, rv, cam.T, cam.K, cam.dist, want);
		double worst = 0;
		for (size_t i = 0; i < want.size(); i++)
			worst = std::max(worst, cv::norm(cv::Point2d(v.image_points[i]) - want[i]));
		std::printf("  worst corner %.3f px from the truth\n", worst);
		assert_true(worst < 0.3);
	}
}

// The library on all views: per camera and per pair RMS, accuracy against the truth, and the
// board-pose world frame.
static void test_rig_accuracy(void **)
{
	const std::vector<cv::Size> sizes = camera_sizes();
	int rendered = 0, found = 0;
	for (size_t p = 0; p < fx->views.size(); p++)
		for (size_t c = 0; c < sizes.size(); c++) {
			rendered += fx->rendered[p][c];
			found += fx->views[p][c].found;
		}
	std::printf("  %zu poses, %d views rendered, board found in %d\n", fx->poses.size(), rendered, found);
	const Status &st = recovered();
	std::printf("  %s\n", st.message().c_str());
	assert_true(st.ok());
	const Calibration &got = fx->recovered;
	calib::RigReport rep = fx->recovered_report;
	for (size_t c = 0; c < rep.cameras.size(); c++)
		std::printf("  camera %zu: %d views, RMS %.4f px alone, %.4f px joint\n", c,
			    rep.cameras[c].views, rep.cameras[c].intrinsic_rms_px, rep.cameras[c].final_rms_px);
	for (const calib::PairReport &pr : rep.pairs)
		std::printf("  pair %d-%d: %d views, stereo RMS %.4f px chained, %.4f px joint\n",
			    pr.cam_a, pr.cam_b, pr.views, pr.chain_rms_px, pr.final_rms_px);
	for (const std::string &d : rep.dropped)
		std::printf("  dropped %s\n", d.c_str());
	std::printf("  joint: %d iterations, RMS %.4f px\n", rep.iterations, rep.final_rms_px);
	assert_true(rep.final_rms_px > 0 && rep.final_rms_px < 0.2);
	assert_int_equal(rep.pairs.size(), 3);
	for (const calib::PairReport &pr : rep.pairs)
		assert_true(pr.views >= 2 && pr.final_rms_px < 0.2);
	// Camera 0 is the world: identity pose.
	assert_true(cv::norm(got.cameras[0].R - cv::Matx33d::eye()) < 1e-12);
	assert_true(cv::norm(got.cameras[0].T) < 1e-12);
	assert_within_issue_tolerance(compare(got, truth_in_camera_frame(fx->truth.cameras, 0)));

	// World = the board in pose 10.
	calib::CalibParams params;
	params.origin_pose = 10;
	Calibration on_board;
	assert_true(calib::calibrate_rig(fx->views, sizes, params, &on_board, &rep).ok());
	std::printf("  world frame: %s\n", rep.world_frame.c_str());
	const sim::BoardPose &b = fx->poses[10];
	std::vector<CameraModel> want;
	for (const CameraModel &c : fx->truth.cameras) {
		CameraModel m = c;
		m.R = c.R * b.R;
		m.T = c.R * b.t + c.T;
		want.push_back(m);
	}
	assert_within_issue_tolerance(compare(on_board, want));
	params.origin_pose = 999;
	assert_false(calib::calibrate_rig(fx->views, sizes, params, &on_board, &rep).ok());
}

// `facescan calibrate --dir`: all four cameras, from the files.
static void test_cli_multi_camera(void **)
{
	const std::string out = fx->dir + "/out/calibration.yaml";
	fs::create_directories(fx->dir + "/out");
	assert_int_equal(run_cli({"--dir", fx->dir, "--board", "9x6", "--square-mm", "25", "--id",
				  "test-rig", "-o", out}),
			 0);
	Calibration got;
	Status st = read_calibration(out, &got);
	assert_true(st.ok());
	assert_string_equal(got.id.c_str(), "test-rig");
	assert_within_issue_tolerance(compare(got, truth_in_camera_frame(fx->truth.cameras, 0)));
}

// Two-camera mode on cameras 1 and 2 (the common stereo set-up), from a pair list.
static void test_cli_pairs(void **)
{
	const std::string list = fx->dir + "/pairs.txt";
	{
		std::ofstream f(list);
		f << "# left right\n";
		for (size_t p = 0; p < fx->poses.size(); p++)
			f << "pose" << p << "_cam1.png   pose" << p << "_cam2.png\n";
	}
	const std::string out = fx->dir + "/stereo.yaml";
	assert_int_equal(run_cli({"--pairs", list, "--board", "9x6", "--square-mm", "25", "-o", out}), 0);
	Calibration got;
	assert_true(read_calibration(out, &got).ok());
	assert_int_equal(got.cameras.size(), 2);
	assert_true(cv::norm(got.cameras[0].R - cv::Matx33d::eye()) < 1e-12);
	assert_true(cv::norm(got.cameras[0].T) < 1e-12);
	const std::vector<CameraModel> pair = {fx->truth.cameras[1], fx->truth.cameras[2]};
	assert_within_issue_tolerance(compare(got, truth_in_camera_frame(pair, 0)));
}

// Bad inputs: a clear error, the right exit code, and no file.
static void test_cli_bad_inputs(void **)
{
	const std::string out = fx->dir + "/bad.yaml";
	const std::string list = fx->dir + "/bad.txt";
	auto write_list = [&](const std::string &text) {
		std::ofstream f(list);
		f << text;
	};
	// A line with three images.
	write_list("pose0_cam1.png pose0_cam2.png\npose1_cam1.png pose1_cam2.png pose2_cam2.png\n");
	assert_int_equal(run_cli({"--pairs", list, "--board", "9x6", "--square-mm", "25", "-o", out}), 1);
	assert_false(exists(out));
	// A line with one image.
	write_list("pose0_cam1.png\n");
	assert_int_equal(run_cli({"--pairs", list, "--board", "9x6", "--square-mm", "25", "-o", out}), 1);
	assert_false(exists(out));
	// Too few good views: two pairs, one of them a missing file.
	write_list("pose4_cam1.png pose4_cam2.png\nmissing.png pose5_cam2.png\n");
	assert_int_equal(run_cli({"--pairs", list, "--board", "9x6", "--square-mm", "25", "-o", out}), 1);
	assert_false(exists(out));
	// No board in any image.
	const cv::Size size = fx->truth.cameras[0].size;
	assert_true(cv::imwrite(fx->dir + "/blank.png", cv::Mat(size, CV_8U, cv::Scalar(128))));
	write_list("blank.png blank.png\nblank.png blank.png\nblank.png blank.png\nblank.png blank.png\n");
	assert_int_equal(run_cli({"--pairs", list, "--board", "9x6", "--square-mm", "25", "-o", out}), 1);
	assert_false(exists(out));
	// The wrong board size: nothing found.
	write_list("pose4_cam1.png pose4_cam2.png\npose5_cam1.png pose5_cam2.png\n"
		   "pose6_cam1.png pose6_cam2.png\npose7_cam1.png pose7_cam2.png\n");
	assert_int_equal(run_cli({"--pairs", list, "--board", "7x4", "--square-mm", "25", "-o", out}), 1);
	assert_false(exists(out));
	// Bad arguments: exit 2.
	assert_int_equal(run_cli({"--pairs", list, "--board", "8x6", "--square-mm", "25", "-o", out}), 2);
	assert_int_equal(run_cli({"--pairs", list, "--square-mm", "25", "-o", out}), 2);
	assert_int_equal(run_cli({"--pairs", list, "--dir", fx->dir, "--board", "9x6", "--square-mm",
				  "25", "-o", out}),
			 2);
	assert_int_equal(run_cli({"--pairs", list, "--board", "9x6", "--square-mm", "-3", "-o", out}), 2);
	assert_false(exists(out));
	// A directory without pose<k>_cam<i> images.
	fs::create_directories(fx->dir + "/empty");
	assert_int_equal(run_cli({"--dir", fx->dir + "/empty", "--board", "9x6", "--square-mm", "25",
				  "-o", out}),
			 1);
	assert_false(exists(out));
}

// A face reconstructed with the recovered calibration stays within the reconstruction issue's
// floor (vertex RMS <= 0.3 mm) and covers what the true calibration covers (within 3 points).
// The recovered world is camera 0's frame; the mesh is mapped back to the rig's world with the
// TRUE camera 0 pose, so any error of the recovered rig shows in the comparison.
static void test_recon_with_recovered_calibration(void **)
{
	assert_true(recovered().ok());
	const Calibration &got = fx->recovered;

	const sim::Rig rig = sim::default_rig();
	testing::SimulatedScan scan; // a head no other test uses
	assert_true(testing::simulate_scan(rig, sim::random_head_shape(7), 7, &scan).ok());
	const std::vector<CameraModel> projectors = sim::projector_models(rig);

	struct Run {
		const char *name;
		eval::EvalResult r;
	} runs[2] = {{"true calibration", {}}, {"recovered calibration", {}}};
	for (int k = 0; k < 2; k++) {
		CaptureSet s = scan.set;
		if (k == 1)
			s.calibration = got;
		recon::Mesh mesh;
		recon::ReconReport report;
		const Status st = recon::reconstruct(s, scan.pattern, recon::ReconParams(), &mesh, &report);
		if (!st.ok())
			std::printf("  reconstruct: %s\n", st.message().c_str());
		assert_true(st.ok());
		if (k == 1) { // camera-0 frame -> rig world: X = R0^T (p - T0)
			const CameraModel &c0 = fx->truth.cameras[0];
			for (cv::Point3f &p : mesh.positions) {
				const cv::Vec3d w = c0.R.t() * (cv::Vec3d(p.x, p.y, p.z) - c0.T);
				p = cv::Point3f(float(w[0]), float(w[1]), float(w[2]));
			}
		}
		assert_true(eval::evaluate(mesh, scan.truth, fx->truth.cameras, projectors, eval::EvalParams(),
					   &runs[k].r).ok());
		std::printf("  %s: %d vertices, RMS %.3f mm, median %.3f, p95 %.3f, completeness %.1f %%\n",
			    runs[k].name, runs[k].r.vertices, runs[k].r.rms_mm, runs[k].r.median_mm, runs[k].r.p95_mm,
			    100 * runs[k].r.completeness);
	}
	assert_true(runs[1].r.rms_mm <= 0.3);
	assert_true(runs[1].r.p95_mm <= 0.8);
	assert_true(std::fabs(runs[1].r.completeness - runs[0].r.completeness) <= 0.03);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_board_description),
		cmocka_unit_test(test_corner_order),
		cmocka_unit_test(test_charuco_detection),
		cmocka_unit_test(test_rig_accuracy),
		cmocka_unit_test(test_recon_with_recovered_calibration),
		cmocka_unit_test(test_cli_multi_camera),
		cmocka_unit_test(test_cli_pairs),
		cmocka_unit_test(test_cli_bad_inputs),
	};
	if (const char *only = std::getenv("CALIB_TEST_ONLY"))
		cmocka_set_test_filter(only);
	return cmocka_run_group_tests(tests, setup, teardown);
}
