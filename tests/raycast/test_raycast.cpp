// host/raycast against geometry with known answers: a unit square at z = 10 and a second one
// behind it, hits with their distance, mesh index, triangle and barycentrics; misses; occlusion
// bounded by t_far; malformed meshes refused by name and the tracer left as it was.
#include "raycast/raycast.hpp"

#include "recon/cmocka.hpp"

#include <cmath>
#include <cstring>
#include <limits>

using namespace facescan;

namespace {

// Two triangles over [-1, 1]^2 at depth z, facing -z.
void square(float z, std::vector<cv::Vec3f> *v, std::vector<cv::Vec3i> *t)
{
	*v = {{-1, -1, z}, {1, -1, z}, {1, 1, z}, {-1, 1, z}};
	*t = {{0, 1, 2}, {0, 2, 3}};
}

void test_hits_and_misses(void **)
{
	std::vector<cv::Vec3f> va, vb;
	std::vector<cv::Vec3i> ta, tb;
	square(10, &va, &ta);
	square(20, &vb, &tb);
	raycast::Tracer tracer;
	assert_true(tracer.build({{&va, &ta}, {&vb, &tb}}).ok());
	// Straight down the axis from the origin: the near square, 10 mm away.
	raycast::Hit h = tracer.intersect(cv::Vec3d(0.5, -0.25, 0), cv::Vec3d(0, 0, 3));
	assert_int_equal(h.surface, 0);
	assert_true(std::fabs(h.t - 10.0f) < 1e-4f);
	assert_int_equal(h.triangle, 0); // below the diagonal x = y
	// The barycentrics give back the hit point: p = (1-u-v) v0 + u v1 + v v2.
	const cv::Vec3f p = va[0] * (1 - h.u - h.v) + va[1] * h.u + va[2] * h.v;
	assert_true(std::fabs(p[0] - 0.5f) < 1e-4f && std::fabs(p[1] + 0.25f) < 1e-4f);
	// Starting past the first square: the second one.
	h = tracer.intersect(cv::Vec3d(0, 0.5, 0), cv::Vec3d(0, 0, 1), 12.0);
	assert_int_equal(h.surface, 1);
	assert_true(std::fabs(h.t - 20.0f) < 1e-4f);
	// Beside both, and away from both.
	assert_int_equal(tracer.intersect(cv::Vec3d(3, 0, 0), cv::Vec3d(0, 0, 1)).surface, -1);
	assert_int_equal(tracer.intersect(cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, -1)).surface, -1);
	// Occlusion only within (t_near, t_far).
	assert_true(tracer.occluded(cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 1), 0, 15));
	assert_false(tracer.occluded(cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 1), 0, 5));
	assert_false(tracer.occluded(cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 1), 21, 100));
}

void test_malformed_meshes_refused(void **)
{
	std::vector<cv::Vec3f> v;
	std::vector<cv::Vec3i> t;
	square(10, &v, &t);
	raycast::Tracer tracer;
	assert_true(tracer.build({{&v, &t}}).ok());

	std::vector<cv::Vec3i> bad_index = {{0, 1, 4}};
	Status s = tracer.build({{&v, &t}, {&v, &bad_index}});
	assert_false(s.ok());
	assert_int_equal(s.code(), -EINVAL);
	assert_non_null(std::strstr(s.message().c_str(), "mesh 1"));
	std::vector<cv::Vec3f> nan_vertex = v;
	nan_vertex[2][1] = std::numeric_limits<float>::quiet_NaN();
	assert_int_equal(tracer.build({{&nan_vertex, &t}}).code(), -EINVAL);
	std::vector<cv::Vec3i> none;
	assert_int_equal(tracer.build({{&v, &none}}).code(), -EINVAL);
	assert_int_equal(tracer.build({{nullptr, &t}}).code(), -EINVAL);
	// The scene built before the failures still answers.
	assert_int_equal(tracer.intersect(cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 1)).surface, 0);
	// An empty tracer misses everything.
	raycast::Tracer empty;
	assert_int_equal(empty.intersect(cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 1)).surface, -1);
	assert_false(empty.occluded(cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 1), 0, 100));
}

} // namespace

int main()
{
	const CMUnitTest tests[] = {
		cmocka_unit_test(test_hits_and_misses),
		cmocka_unit_test(test_malformed_meshes_refused),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
