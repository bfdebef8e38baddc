// Stage 6: triangulation of exact-plus-noise matches of a known plane and sphere through
// distorted cameras; a gross mismatch is dropped by its reprojection error.
#include "recon/triangulate.hpp"

#include "cmocka.hpp"
#include "synthetic_rig.hpp"

#include <cstdio>

using namespace facescan::recon;

static void test_plane(void **)
{
	const auto cams = synth::ring();
	// A tilted plane through (0, 0, 20): normal n.
	cv::Vec3d n(0.15, 0.1, 1.0);
	n *= 1.0 / cv::norm(n);
	const cv::Vec3d u = cv::Vec3d(0, 1, 0).cross(n) * (1.0 / cv::norm(cv::Vec3d(0, 1, 0).cross(n)));
	const cv::Vec3d v = n.cross(u);
	std::vector<cv::Point3d> pts;
	std::vector<cv::Vec3d> normals;
	for (double s = -60; s <= 60; s += 4)
		for (double t = -50; t <= 50; t += 4) {
			pts.push_back(cv::Point3d(0, 0, 20) + cv::Point3d(u * s + v * t));
			normals.push_back(n);
		}
	PairMatches pm = synth::matches(cams, 1, 2, pts, normals, 0.1, 7);
	// One gross mismatch: camera b's point moved 25 px off the epipolar line.
	PointMatch bad = pm.matches[10];
	bad.b.y += 25;
	bad.square_a = bad.square_b = 99999;
	pm.matches.push_back(bad);

	PartialModel model;
	TriangulateStats st;
	assert_true(triangulate_pair(pm, cams[1], cams[2], {}, &model, &st).ok());
	std::printf("plane: %d in, %d kept, %d dropped (reprojection), mean %.3f px\n", st.input, st.kept,
		    st.dropped_reprojection, st.mean_reprojection_px);
	assert_int_equal(st.dropped_reprojection, 1);
	assert_int_equal(st.kept, st.input - 1);
	assert_true(st.kept > 500);
	// Plane-fit residual and distance to the true plane.
	double ss = 0, truth = 0;
	cv::Point3d c(0, 0, 0);
	for (const cv::Point3d &p : model.points)
		c += p;
	c *= 1.0 / double(model.points.size());
	cv::Mat A(int(model.points.size()), 3, CV_64F);
	for (int i = 0; i < A.rows; ++i) {
		const cv::Point3d d = model.points[size_t(i)] - c;
		A.at<double>(i, 0) = d.x;
		A.at<double>(i, 1) = d.y;
		A.at<double>(i, 2) = d.z;
		const double e = cv::Vec3d(model.points[size_t(i)] - cv::Point3d(0, 0, 20)).dot(n);
		truth += e * e;
	}
	cv::SVD svd(A);
	const cv::Vec3d fn(svd.vt.at<double>(2, 0), svd.vt.at<double>(2, 1), svd.vt.at<double>(2, 2));
	for (const cv::Point3d &p : model.points) {
		const double e = cv::Vec3d(p - c).dot(fn);
		ss += e * e;
	}
	const double fit_rms = std::sqrt(ss / double(model.points.size()));
	const double truth_rms = std::sqrt(truth / double(model.points.size()));
	std::printf("plane: fit residual RMS %.4f mm, distance to true plane RMS %.4f mm\n", fit_rms, truth_rms);
	assert_true(fit_rms < 0.08);
	assert_true(truth_rms < 0.08);
	assert_true(std::fabs(fn.dot(n)) > 0.9999);
}

static void test_sphere(void **)
{
	const auto cams = synth::ring();
	std::vector<cv::Point3d> pts;
	std::vector<cv::Vec3d> normals;
	const cv::Point3d centre(5, -10, -60);
	synth::sphere(centre, 80, 3, &pts, &normals);
	for (int pair = 0; pair < 3; ++pair) {
		const PairMatches pm = synth::matches(cams, pair, pair + 1, pts, normals, 0.1, 11u + unsigned(pair));
		PartialModel model;
		TriangulateStats st;
		assert_true(triangulate_pair(pm, cams[size_t(pair)], cams[size_t(pair + 1)], {}, &model, &st).ok());
		assert_true(st.kept > 200);
		assert_int_equal(st.dropped_reprojection, 0);
		cv::Point3d c;
		const double r = synth::fit_sphere(model.points, &c);
		double worst = 0;
		for (const cv::Point3d &p : model.points)
			worst = std::max(worst, std::fabs(cv::norm(p - centre) - 80));
		std::printf("sphere pair %d-%d: %d points, radius %.4f mm (true 80), centre off %.4f mm, "
			    "worst %.3f mm\n", pair, pair + 1, st.kept, r, cv::norm(c - centre), worst);
		assert_true(std::fabs(r - 80) < 0.1);
		assert_true(cv::norm(c - centre) < 0.2);
		assert_true(worst < 0.4);
	}
}

static void test_bad_camera(void **)
{
	auto cams = synth::ring();
	cams[2].K = cv::Matx33d::zeros();
	PairMatches pm;
	pm.cam_a = 1;
	pm.cam_b = 2;
	PartialModel model;
	assert_int_equal(triangulate_pair(pm, cams[1], cams[2], {}, &model, nullptr).code(), -EINVAL);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_plane),
		cmocka_unit_test(test_sphere),
		cmocka_unit_test(test_bad_camera),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
