// Stage 7: Delaunay meshing per pair; no triangle may bridge a depth jump.
#include "recon/meshing.hpp"
#include "recon/triangulate.hpp"

#include "cmocka.hpp"
#include "synthetic_rig.hpp"

#include <cstdio>
#include <map>

using namespace facescan::recon;

static void test_delaunay_square_grid(void **)
{
	std::vector<cv::Point2d> sites;
	for (int j = 0; j < 5; ++j)
		for (int i = 0; i < 6; ++i)
			sites.emplace_back(i * 3.0 + 100, j * 3.0 - 7);
	sites.push_back(sites[7]); // a duplicate collapses onto the first
	const std::vector<cv::Vec3i> tris = delaunay_2d(sites);
	// A 6x5 lattice: 2 * 5 * 4 triangles, all counter-clockwise, none using the duplicate.
	assert_int_equal(tris.size(), 40);
	for (const cv::Vec3i &t : tris) {
		const cv::Point2d a = sites[size_t(t[0])], b = sites[size_t(t[1])], c = sites[size_t(t[2])];
		assert_true((b - a).cross(c - a) > 0);
		for (int k = 0; k < 3; ++k)
			assert_true(t[k] < 30);
	}
}

static void test_no_edges_across_depth_jump(void **)
{
	const auto cams = synth::ring();
	// Two fronto-parallel sheets side by side: x < 0 at z = 0, x >= 0 at z = -40 (a step).
	std::vector<cv::Point3d> pts;
	std::vector<cv::Vec3d> normals;
	std::vector<int> sheet;
	for (double x = -60; x <= 60; x += 3)
		for (double y = -50; y <= 50; y += 3) {
			const bool far = x >= 0;
			pts.emplace_back(x, y, far ? -40.0 : 0.0);
			normals.emplace_back(0, 0, 1);
			sheet.push_back(far);
		}
	const PairMatches pm = synth::matches(cams, 1, 2, pts, normals, 0.05, 3);
	PartialModel model;
	assert_true(triangulate_pair(pm, cams[1], cams[2], {}, &model, nullptr).ok());
	MeshingStats st;
	assert_true(mesh_partial(cams[1], cams[2], {}, &model, &st).ok());
	std::printf("depth jump: %d Delaunay, %d kept, %d too long, %d grazing, median edge %.2f mm\n",
		    st.delaunay, st.kept, st.dropped_long, st.dropped_grazing, st.median_edge_mm);
	int per_sheet[2] = {0, 0};
	const cv::Vec3d eye = (cams[1].centre() + cams[2].centre()) * 0.5;
	for (const cv::Vec3i &t : model.triangles) {
		const int s0 = sheet[size_t(model.sources[size_t(t[0])].square_a)];
		for (int k = 1; k < 3; ++k)
			assert_int_equal(sheet[size_t(model.sources[size_t(t[k])].square_a)], s0);
		per_sheet[s0]++;
		// Oriented towards the cameras.
		const cv::Point3d a = model.points[size_t(t[0])], b = model.points[size_t(t[1])],
				  c = model.points[size_t(t[2])];
		assert_true(cv::Vec3d((b - a).cross(c - a)).dot(eye - cv::Vec3d(a)) > 0);
	}
	assert_true(st.dropped_long + st.dropped_grazing > 0);
	// Both sheets stay meshed: ~2 triangles per lattice point each.
	assert_true(per_sheet[0] > 300 && per_sheet[1] > 300);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_delaunay_square_grid),
		cmocka_unit_test(test_no_edges_across_depth_jump),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
