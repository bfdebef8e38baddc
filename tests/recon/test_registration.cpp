// Stage 8: registration recovers a known R, T between partial models linked through their
// shared camera, and reports the paper's D before and after.
#include "recon/registration.hpp"
#include "recon/triangulate.hpp"

#include "cmocka.hpp"
#include <opencv2/calib3d.hpp>
#include "synthetic_rig.hpp"

#include <cstdio>
#include <limits>

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

// A dense cloud: points on the sphere |x - c| = r, ~0.5 mm apart, with longitude in [lon0, lon1]
// (degrees about y) and latitude within ±30°.
static std::vector<cv::Point3f> sphere_patch(double lon0, double lon1)
{
	const cv::Vec3d c(0, 0, -60);
	const double r = 85, step = 0.5 / r;
	std::vector<cv::Point3f> out;
	for (double lat = -0.52; lat <= 0.52; lat += step)
		for (double lon = lon0 * CV_PI / 180; lon <= lon1 * CV_PI / 180; lon += step / std::cos(lat))
			out.emplace_back(cv::Vec3f(c + r * cv::Vec3d(std::cos(lat) * std::sin(lon), std::sin(lat),
								    std::cos(lat) * std::cos(lon))));
	return out;
}

static void test_dense_overlap_distance(void **)
{
	const std::vector<cv::Point3f> a = sphere_patch(-40, 10), b = sphere_patch(-10, 40);
	RegistrationParams params;
	double before = 0, after = 0;
	// On the same surface the distance is the sampling's (under half the 0.5 mm spacing) and that
	// of the points just past the other cloud's edge (within reach); 0.8 mm along the normal near
	// the overlap adds about that.
	const cv::Vec3d out_of_surface(0, 0, 0.8);
	assert_true(overlap_distance(a, b, cv::Matx33d::eye(), out_of_surface, params, &before, &after).ok());
	std::printf("overlap distance: %.3f mm in place, %.3f mm moved 0.8 mm\n", before, after);
	assert_true(before < 0.35);
	assert_true(after - before > 0.5 && after - before < 0.9);
	// Clouds far apart do not overlap.
	const std::vector<cv::Point3f> far = sphere_patch(100, 140);
	assert_int_equal(overlap_distance(a, far, cv::Matx33d::eye(), cv::Vec3d(0, 0, 0), params, &before, &after).code(),
			 -ENODATA);
	assert_int_equal(overlap_distance({}, b, cv::Matx33d::eye(), cv::Vec3d(0, 0, 0), params, &before, &after).code(),
			 -ENODATA);
}

// The overlap distance is exact: the same mean as a brute-force nearest point search, on clouds
// that straddle the coordinate axes (cells on both sides of 0) and carry a point at infinity.
static void test_dense_overlap_distance_is_exact(void **)
{
	cv::RNG rng(11);
	std::vector<cv::Point3f> fixed, moving;
	for (int i = 0; i < 1500; ++i) {
		fixed.emplace_back(float(rng.uniform(-30.0, 30.0)), float(rng.uniform(-30.0, 30.0)),
				   float(rng.uniform(-3.0, 3.0)));
		moving.emplace_back(float(rng.uniform(-50.0, 10.0)), float(rng.uniform(-30.0, 30.0)),
				    float(rng.uniform(-6.0, 6.0)));
	}
	fixed.emplace_back(std::numeric_limits<float>::infinity(), 0.f, 0.f);
	RegistrationParams params;
	params.dense_stride = 3;
	const cv::Matx33d R = cv::Matx33d::eye();
	const cv::Vec3d T(1.5, -0.5, 0.7);
	double before = 0, after = 0;
	assert_true(overlap_distance(moving, fixed, R, T, params, &before, &after).ok());
	auto nearest = [&](const cv::Vec3d &q) {
		double best = std::numeric_limits<double>::infinity();
		for (const cv::Point3f &f : fixed)
			if (std::isfinite(f.x))
				best = std::min(best, cv::norm(cv::Vec3d(f.x, f.y, f.z) - q));
		return best;
	};
	double sum0 = 0, sum1 = 0;
	int count = 0;
	for (size_t i = 0; i < moving.size(); i += size_t(params.dense_stride)) {
		const cv::Vec3d q(moving[i].x, moving[i].y, moving[i].z);
		const double a = nearest(q), b = nearest(R * q + T);
		if (a > params.dense_reach_mm && b > params.dense_reach_mm)
			continue;
		sum0 += std::min(a, params.dense_cap_mm);
		sum1 += std::min(b, params.dense_cap_mm);
		count++;
	}
	assert_true(count > 100);
	std::printf("overlap distance: %.4f / %.4f mm, brute force %.4f / %.4f mm over %d points\n", before, after,
		    sum0 / count, sum1 / count, count);
	assert_true(std::fabs(before - sum0 / count) < 1e-4);
	assert_true(std::fabs(after - sum1 / count) < 1e-4);
}

static void test_dense_check_keeps_good_fits_only(void **)
{
	const std::vector<cv::Point3f> left = sphere_patch(-40, 10), middle = sphere_patch(-15, 15),
				       right = sphere_patch(-10, 40);
	// The left cloud is off by a known motion and its code fit undoes it; the right cloud is in
	// place and its code fit (a few noisy code points) would move it 0.7 mm.
	const cv::Matx33d Roff = rotation(cv::Vec3d(0.0, 0.01, 0.005));
	const cv::Vec3d Toff(1.0, -0.5, 0.8);
	std::vector<std::vector<cv::Point3f>> clouds = {left, middle, right};
	for (cv::Point3f &q : clouds[0])
		q = cv::Point3f(Roff * cv::Vec3d(q.x, q.y, q.z) + Toff);
	std::vector<RegistrationPair> pairs(2);
	pairs[0].model = 0;
	pairs[0].onto = 1;
	pairs[0].applied = true;
	pairs[0].R = Roff.t();
	pairs[0].T = -(Roff.t() * Toff);
	pairs[1].model = 2;
	pairs[1].onto = 1;
	pairs[1].applied = true;
	pairs[1].R = rotation(cv::Vec3d(0.002, -0.003, 0.0));
	pairs[1].T = cv::Vec3d(-0.2, 0.6, 0.3);
	assert_true(register_dense(&clouds, {}, &pairs).ok());
	for (const RegistrationPair &rp : pairs)
		std::printf("model %d: dense overlap %.3f -> %.3f mm, kept %d\n", rp.model, rp.dense_before_mm,
			    rp.dense_after_mm, rp.applied_dense);
	assert_true(pairs[0].applied_dense);
	assert_true(pairs[0].dense_after_mm < 0.4 * pairs[0].dense_before_mm);
	double worst = 0;
	for (size_t i = 0; i < left.size(); ++i)
		worst = std::max(worst, double(cv::norm(clouds[0][i] - left[i])));
	assert_true(worst < 1e-3);
	assert_false(pairs[1].applied_dense);
	assert_true(pairs[1].dense_after_mm > pairs[1].dense_before_mm);
	assert_true(clouds[2] == right);
	// A fit the code did not apply is not applied by the dense check either.
	std::vector<RegistrationPair> none(1);
	none[0].model = 0;
	none[0].onto = 1;
	none[0].R = pairs[0].R;
	none[0].T = pairs[0].T;
	std::vector<std::vector<cv::Point3f>> again = {left, middle};
	assert_true(register_dense(&again, {}, &none).ok());
	assert_false(none[0].applied_dense);
	assert_true(again[0] == left);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_rigid_fit_exact),
		cmocka_unit_test(test_recovers_known_motion),
		cmocka_unit_test(test_exact_calibration_left_alone),
		cmocka_unit_test(test_dense_overlap_distance),
		cmocka_unit_test(test_dense_overlap_distance_is_exact),
		cmocka_unit_test(test_dense_check_keeps_good_fits_only),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
