// Stage 9: fusion weights, border distances, and one sheet without duplicates or cracks from
// three overlapping partial models of a sphere.
#include "recon/fusion.hpp"
#include "recon/meshing.hpp"
#include "recon/triangulate.hpp"

#include "cmocka.hpp"
#include "synthetic_rig.hpp"

#include <cstdio>
#include <functional>
#include <map>
#include <set>

using namespace facescan::recon;

static void test_blend_weights(void **)
{
	const std::vector<cv::Point3d> copies = {{0, 0, 0}, {10, 0, 0}};
	// A copy on its model's border gets only the floor weight: 0.5 vs 10.5.
	const cv::Point3d p = blend(copies, {0.0, 10.0}, 0.5);
	assert_true(std::fabs(p.x - 10.0 * 10.5 / 11.0) < 1e-12);
	// Equal distances: the midpoint.
	assert_true(std::fabs(blend(copies, {4.0, 4.0}, 0.5).x - 5.0) < 1e-12);
	// Farther from the border weighs more.
	assert_true(blend(copies, {8.0, 2.0}, 0.5).x < 5.0);
}

static void test_border_distances(void **)
{
	// A 7x7 lattice, 2 mm apart, meshed as a grid: distance = steps to the outer ring * 2 mm.
	PartialModel m;
	const int n = 7;
	for (int j = 0; j < n; ++j)
		for (int i = 0; i < n; ++i)
			m.points.emplace_back(i * 2.0, j * 2.0, 0.0);
	for (int j = 0; j + 1 < n; ++j)
		for (int i = 0; i + 1 < n; ++i) {
			const int a = j * n + i;
			m.triangles.emplace_back(a, a + 1, a + n);
			m.triangles.emplace_back(a + 1, a + n + 1, a + n);
		}
	m.points.emplace_back(100.0, 100.0, 0.0); // in no triangle
	const std::vector<double> d = border_distances(m);
	for (int j = 0; j < n; ++j)
		for (int i = 0; i < n; ++i) {
			const int ring = std::min({i, j, n - 1 - i, n - 1 - j});
			assert_true(std::fabs(d[size_t(j * n + i)] - 2.0 * ring) < 1e-9);
		}
	assert_true(d.back() == 0.0);
}

static void test_three_models_one_sheet(void **)
{
	const auto cams = synth::ring();
	std::vector<cv::Point3d> pts;
	std::vector<cv::Vec3d> normals;
	const cv::Point3d centre(0, 0, -60);
	synth::sphere(centre, 85, 3, &pts, &normals);
	std::vector<PartialModel> models(3);
	std::set<int> seen;
	for (int p = 0; p < 3; ++p) {
		const PairMatches pm = synth::matches(cams, p, p + 1, pts, normals, 0.1, 40u + unsigned(p));
		PartialModel &m = models[size_t(p)];
		assert_true(triangulate_pair(pm, cams[size_t(p)], cams[size_t(p + 1)], {}, &m, nullptr).ok());
		assert_true(mesh_partial(cams[size_t(p)], cams[size_t(p + 1)], {}, &m, nullptr).ok());
		for (const PointMatch &s : m.sources)
			seen.insert(s.square_a);
	}
	Mesh mesh;
	FusionStats st;
	assert_true(fuse_models(models, cams, {}, &mesh, &st).ok());
	std::printf("fusion: %d input points, %d distinct, %d vertices (%d merged), %d triangles\n",
		    st.input_points, int(seen.size()), st.vertices, st.merged, st.triangles);
	// Every distinct grid point once: no duplicates of shared points.
	assert_true(st.vertices <= int(seen.size()));
	assert_true(st.vertices > int(seen.size()) * 95 / 100);
	assert_true(st.merged > 1000);
	assert_int_equal(mesh.normals.size(), mesh.positions.size());
	double worst = 0;
	for (const cv::Point3f &p : mesh.positions)
		worst = std::max(worst, std::fabs(cv::norm(cv::Point3d(p) - centre) - 85));
	std::printf("fusion: worst radial error %.3f mm\n", worst);
	assert_true(worst < 0.3);
	// One sheet: every edge in at most two triangles, consistently oriented outwards, and the
	// boundary is a single loop (no cracks between the models).
	std::map<std::pair<int, int>, int> directed;
	for (const cv::Vec3i &t : mesh.triangles) {
		for (int k = 0; k < 3; ++k)
			assert_int_equal(directed[std::make_pair(t[k], t[(k + 1) % 3])]++, 0);
		const cv::Point3f a = mesh.positions[size_t(t[0])], b = mesh.positions[size_t(t[1])],
				  c = mesh.positions[size_t(t[2])];
		assert_true(cv::Point3d((b - a).cross(c - a)).dot(cv::Point3d(a) - centre) > 0);
	}
	// Boundary edges (no reverse twin), grouped into connected components of the boundary graph.
	std::map<int, int> parent;
	std::function<int(int)> find = [&](int v) { return parent[v] == v ? v : parent[v] = find(parent[v]); };
	int boundary = 0;
	for (const auto &[e, count] : directed) {
		(void)count;
		if (directed.count({e.second, e.first}))
			continue;
		boundary++;
		for (int v : {e.first, e.second})
			if (!parent.count(v))
				parent[v] = v;
		parent[find(e.first)] = find(e.second);
	}
	int loops = 0;
	for (const auto &entry : parent)
		loops += find(entry.first) == entry.first;
	std::printf("fusion: %d boundary edges in %d loop(s)\n", boundary, loops);
	assert_int_equal(loops, 1);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_blend_weights),
		cmocka_unit_test(test_border_distances),
		cmocka_unit_test(test_three_models_one_sheet),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
