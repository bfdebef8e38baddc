// host/eval: point-triangle distance, and metrics of a known offset surface.
#include "eval/eval.hpp"

#include "cmocka.hpp"
#include "synthetic_rig.hpp"

#include <cmath>
#include <cstdio>

using namespace facescan;

static void test_point_triangle_distance(void **)
{
	const cv::Point3d a(0, 0, 0), b(10, 0, 0), c(0, 10, 0);
	assert_true(std::fabs(eval::point_triangle_distance({2, 2, 3}, a, b, c) - 3) < 1e-12);     // face
	assert_true(std::fabs(eval::point_triangle_distance({-3, -4, 0}, a, b, c) - 5) < 1e-12);   // vertex a
	assert_true(std::fabs(eval::point_triangle_distance({5, -2, 0}, a, b, c) - 2) < 1e-12);    // edge ab
	assert_true(std::fabs(eval::point_triangle_distance({6, 6, 0}, a, b, c) - std::sqrt(2.0)) < 1e-12); // edge bc
}

// A UV-sphere patch facing +z of radius r.
static recon::Mesh sphere(double r)
{
	recon::Mesh m;
	const int nu = 120, nv = 80;
	for (int j = 0; j <= nv; ++j)
		for (int i = 0; i <= nu; ++i) {
			const double el = (-60 + 120.0 * j / nv) * CV_PI / 180, az = (-80 + 160.0 * i / nu) * CV_PI / 180;
			m.positions.emplace_back(float(r * std::cos(el) * std::sin(az)), float(r * std::sin(el)),
						 float(r * std::cos(el) * std::cos(az) - 60));
		}
	for (int j = 0; j < nv; ++j)
		for (int i = 0; i < nu; ++i) {
			const int a = j * (nu + 1) + i;
			m.triangles.emplace_back(a, a + 1, a + nu + 2);
			m.triangles.emplace_back(a, a + nu + 2, a + nu + 1);
		}
	return m;
}

static void test_offset_surface(void **)
{
	const recon::Mesh truth = sphere(85), recon = sphere(85.2);
	eval::EvalResult r;
	assert_true(eval::evaluate(recon, truth, synth::ring(), {}, eval::EvalParams(), &r).ok());
	std::printf("offset 0.2 mm: RMS %.4f median %.4f p95 %.4f, completeness %.3f of %d\n", r.rms_mm, r.median_mm,
		    r.p95_mm, r.completeness, r.truth_counted);
	assert_true(std::fabs(r.rms_mm - 0.2) < 0.01);
	assert_true(std::fabs(r.median_mm - 0.2) < 0.01);
	assert_true(r.truth_counted > r.truth_points / 2 && r.truth_counted < r.truth_points);
	assert_true(r.completeness > 0.99);
	eval::EvalParams tight;
	tight.completeness_mm = 0.1;
	assert_true(eval::evaluate(recon, truth, synth::ring(), {}, tight, &r).ok());
	assert_true(r.completeness < 0.01);
	// Half the reconstruction missing: completeness drops to about the half the cameras see.
	recon::Mesh half = recon;
	half.triangles.resize(half.triangles.size() / 2);
	assert_true(eval::evaluate(half, truth, synth::ring(), {}, eval::EvalParams(), &r).ok());
	std::printf("half: completeness %.3f\n", r.completeness);
	assert_true(r.completeness > 0.3 && r.completeness < 0.7);
	// The per-point verdict (facescan evaluate --coverage) adds up to the figures, and the
	// missed points are those far from the half that is left.
	assert_int_equal(r.truth_status.size(), truth.positions.size());
	int counted = 0, covered = 0;
	for (size_t i = 0; i < r.truth_status.size(); ++i) {
		counted += r.truth_status[i] >= 0;
		covered += r.truth_status[i] == 1;
	}
	assert_int_equal(counted, r.truth_counted);
	assert_true(std::abs(double(covered) / counted - r.completeness) < 1e-12);
	eval::MeshDistance to_half(half.positions, half.triangles, 2.0);
	for (size_t i = 0; i < r.truth_status.size(); ++i)
		if (r.truth_status[i] == 0)
			assert_true(to_half.distance(cv::Point3d(truth.positions[i]), 1.0) > 1.0);
	assert_int_equal(eval::evaluate(recon::Mesh(), truth, synth::ring(), {}, {}, &r).code(), -EINVAL);
}

// A vertex duplicated (a texture chart seam: same position, another UV) counts once: 100 copies of
// one vertex 5 mm off change nothing against one copy of it.
static void test_duplicates_count_once(void **)
{
	const recon::Mesh truth = sphere(85);
	recon::Mesh recon = sphere(85.2);
	recon.positions[0] = recon.positions[0] * float(90.2 / 85.2); // 5 mm off
	eval::EvalResult once, many;
	assert_true(eval::evaluate(recon, truth, synth::ring(), {}, eval::EvalParams(), &once).ok());
	recon::Mesh dup = recon;
	for (int k = 0; k < 100; ++k) {
		dup.positions.push_back(recon.positions[0]);
		dup.triangles.emplace_back(int(dup.positions.size()) - 1, 1, 2);
	}
	assert_true(eval::evaluate(dup, truth, synth::ring(), {}, eval::EvalParams(), &many).ok());
	std::printf("one copy: RMS %.5f over %d; 101 copies: RMS %.5f over %d\n", once.rms_mm, once.unique_positions,
		    many.rms_mm, many.unique_positions);
	assert_int_equal(once.unique_positions, int(recon.positions.size()));
	assert_int_equal(many.unique_positions, once.unique_positions);
	assert_true(std::fabs(many.rms_mm - once.rms_mm) < 1e-12);
	assert_true(once.max_mm > 4.9 && once.rms_mm < 0.25);
	// Per vertex (facescan evaluate --errors): every copy carries the distance.
	assert_int_equal(many.vertex_mm.size(), dup.positions.size());
	assert_true(std::fabs(many.vertex_mm[0] - once.max_mm) < 1e-6); // the vertex off the surface
	assert_true(std::fabs(many.vertex_mm.back() - many.vertex_mm[0]) < 1e-6);
	assert_true(std::fabs(many.vertex_mm[5000] - 0.2) < 0.01);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_point_triangle_distance),
		cmocka_unit_test(test_offset_surface),
		cmocka_unit_test(test_duplicates_count_once),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
