// Stage 8: registration recovers a known R, T between partial models linked through their
// shared camera, and reports the paper's D before and after.
#include "recon/registration.hpp"
#include "recon/triangulate.hpp"

#include "cmocka.hpp"
#include <opencv2/calib3d.hpp>
#include "synthetic_rig.hpp"

#include <cstdio>

using namespace facescan::recon;

static std::vector<PartialModel> sphere_models(double noise_px)
{
	const auto cams = synth::ring();
	std::vector<cv::Point3d> pts;
	std::vector<cv::Vec3d> normals;
	synth::sphere(cv::Point3d(0, 0, -60), 85, 3, &pts, &normals);
	std::vector<PartialModel> models(3);
	for (int p = 0; p < 3; ++p) {
		const PairMatches pm = synth::matches(cams, p, p + 1, pts, normals, noise_px, 20u + unsigned(p));
		assert_true(triangulate_pair(pm, cams[size_t(p)], cams[size_t(p + 1)], {}, &models[size_t(p)], nullptr).ok());
	}
	return models;
}

static cv::Matx33d rotation(const cv::Vec3d &axis_angle)
{
	cv::Matx33d R;
	cv::Rodrigues(axis_angle, R);
	return R;
}

static void test_rigid_fit_exact(void **)
{
	const cv::Matx33d R = rotation(cv::Vec3d(0.1, -0.3, 0.2));
	const cv::Vec3d T(12, -4, 30);
	std::vector<cv::Point3d> q, p;
	for (int i = 0; i < 20; ++i) {
		q.emplace_back(std::sin(i) * 50, std::cos(i * 1.7) * 40, i * 2.0);
		p.push_back(cv::Point3d(R * cv::Vec3d(q.back()) + T));
	}
	cv::Matx33d Rf;
	cv::Vec3d Tf;
	assert_true(rigid_fit(q, p, &Rf, &Tf).ok());
	assert_true(cv::norm(Rf - R) < 1e-9);
	assert_true(cv::norm(Tf - T) < 1e-7);
	// Collinear and too few points are refused.
	std::vector<cv::Point3d> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
	assert_int_equal(rigid_fit(line, line, &Rf, &Tf).code(), -EINVAL);
	std::vector<cv::Point3d> two(q.begin(), q.begin() + 2);
	assert_int_equal(rigid_fit(two, two, &Rf, &Tf).code(), -EINVAL);
}

static void test_recovers_known_motion(void **)
{
	std::vector<PartialModel> models = sphere_models(0.1);
	const std::vector<PartialModel> truth = models;
	// Misplace the outer models as a calibration error would.
	const cv::Matx33d R0 = rotation(cv::Vec3d(0.0, 0.03, 0.01));
	const cv::Vec3d T0(2.0, -1.0, 3.0);
	const cv::Matx33d R2 = rotation(cv::Vec3d(-0.02, 0.0, 0.025));
	const cv::Vec3d T2(-1.5, 0.5, -2.5);
	for (cv::Point3d &x : models[0].points)
		x = cv::Point3d(R0 * cv::Vec3d(x) + T0);
	for (cv::Point3d &x : models[2].points)
		x = cv::Point3d(R2 * cv::Vec3d(x) + T2);

	std::vector<RegistrationPair> pairs;
	assert_true(register_models(&models, {}, &pairs).ok());
	assert_int_equal(pairs.size(), 2);
	for (const RegistrationPair &rp : pairs) {
		std::printf("model %d onto %d: %d shared, %d inliers, D %.4f -> %.6f mm^2\n", rp.model, rp.onto,
			    rp.shared, rp.inliers, rp.d_before, rp.d_after);
		assert_int_equal(rp.onto, 1);
		assert_true(rp.applied);
		assert_true(rp.shared > 100);
		assert_true(rp.d_before > 1.0);
		assert_true(rp.d_after < 0.02); // triangulation noise only
	}
	// The recovered motion is the inverse of the one applied; points are back in place.
	const cv::Matx33d Rback = pairs[0].model == 0 ? pairs[0].R : pairs[1].R;
	assert_true(cv::norm(Rback * R0 - cv::Matx33d::eye()) < 2e-3);
	for (int m : {0, 2}) {
		double worst = 0;
		for (size_t i = 0; i < models[size_t(m)].points.size(); ++i)
			worst = std::max(worst, cv::norm(models[size_t(m)].points[i] - truth[size_t(m)].points[i]));
		std::printf("model %d: worst point off its unperturbed place %.4f mm\n", m, worst);
		assert_true(worst < 0.15);
	}
}

static void test_exact_calibration_left_alone(void **)
{
	std::vector<PartialModel> models = sphere_models(0.1);
	const std::vector<PartialModel> before = models;
	std::vector<RegistrationPair> pairs;
	assert_true(register_models(&models, {}, &pairs).ok());
	for (const RegistrationPair &rp : pairs) {
		assert_false(rp.applied);
		assert_true(rp.d_before < 0.02);
	}
	for (size_t m = 0; m < 3; ++m)
		assert_true(models[m].points == before[m].points);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_rigid_fit_exact),
		cmocka_unit_test(test_recovers_known_motion),
		cmocka_unit_test(test_exact_calibration_left_alone),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
