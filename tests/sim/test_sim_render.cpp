// The renderer's geometry and physics against analytic ground truth: a textured plane's corners
// and a sphere's outline land where the calibration (K, distortion, R, T) says, points hidden
// from a projector get none of its light, the same seed gives the same images.
#include "sim/sim.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <map>
#include <tuple>
#include <setjmp.h>

extern "C" {
#include <cmocka.h>
}

using namespace facescan;
using namespace facescan::sim;

static const double kPi = 3.14159265358979323846;

// One 640x480 camera with clear lens distortion, no projectors, flat light.
static Rig test_rig(const cv::Vec3d &eye, const cv::Vec3d &target)
{
	Rig rig;
	SimCamera c;
	c.name = "cam0";
	c.model.size = cv::Size(640, 480);
	c.model.K = cv::Matx33d(820, 0, 322.5, 0, 818, 236.0, 0, 0, 1);
	c.model.dist = cv::Vec<double, 5>(-0.18, 0.09, 0.0015, -0.001, 0);
	look_at(eye, target, 3.0, &c.model.R, &c.model.T);
	c.focus_mm = cv::norm(target - eye);
	rig.cameras.push_back(c);
	rig.lighting.ambient_texture = 0.8;
	rig.lighting.ambient_pattern = 0.02;
	rig.lighting.lights.clear();
	return rig;
}

static cv::Matx33d rot(double ax_deg, double ay_deg)
{
	cv::Vec3d rx(ax_deg * kPi / 180, 0, 0), ry(0, ay_deg * kPi / 180, 0);
	cv::Matx33d Rx, Ry;
	cv::Rodrigues(rx, Rx);
	cv::Rodrigues(ry, Ry);
	return Ry * Rx;
}

static void test_plane_corners_land_on_calibration(void **)
{
	// A 9x7 checkerboard, 180 x 140 mm, tilted, 420 mm in front of the camera.
	const int nx = 9, ny = 7, tex_px = 64;
	cv::Mat tex(ny * tex_px, nx * tex_px, CV_8UC3);
	for (int y = 0; y < tex.rows; y++)
		for (int x = 0; x < tex.cols; x++) {
			bool w = ((x / tex_px) + (y / tex_px)) % 2 == 0;
			tex.at<cv::Vec3b>(y, x) = w ? cv::Vec3b(230, 230, 230) : cv::Vec3b(20, 20, 20);
		}
	Surface board;
	board.mesh = make_plane(180, 140, 4);
	board.texture = tex;
	board.id = 1;
	const cv::Matx33d R = rot(12, -22);
	const cv::Vec3d t(10, -5, 0);
	transform_mesh(R, t, &board.mesh);
	Rig rig = test_rig(cv::Vec3d(0, 0, 420), cv::Vec3d(0, 0, 0));
	rig.supersample = 2;

	RenderOptions opt;
	opt.pattern = false;
	opt.noise = false;
	RenderResult res;
	Status st = render_views(rig, {board}, cv::Mat(), opt, 1, &res);
	assert_true(st.ok());
	assert_int_equal(res.textures.size(), 1);
	cv::Mat gray;
	cv::cvtColor(res.textures[0], gray, cv::COLOR_BGR2GRAY);

	// Inner corners in world coordinates and where the calibration projects them.
	std::vector<cv::Point3d> world;
	for (int j = 1; j < ny; j++)
		for (int i = 1; i < nx; i++) {
			cv::Vec3d p((double(i) / nx - 0.5) * 180, (0.5 - double(j) / ny) * 140, 0);
			world.push_back(cv::Point3d(R * p + t));
		}
	const CameraModel &cm = rig.cameras[0].model;
	cv::Vec3d rvec;
	cv::Rodrigues(cm.R, rvec);
	std::vector<cv::Point2d> want;
	cv::projectPoints(world, rvec, cm.T, cm.K, cm.dist, want);

	// Corners found in the rendered image (detector started from a 2 px offset guess).
	std::vector<cv::Point2f> found;
	for (const cv::Point2d &p : want)
		found.push_back(cv::Point2f(float(p.x + 1.5), float(p.y - 1.5)));
	cv::cornerSubPix(gray, found, cv::Size(6, 6), cv::Size(-1, -1),
			 cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 100, 1e-4));
	double sum = 0, worst = 0;
	for (size_t i = 0; i < want.size(); i++) {
		double e = std::hypot(found[i].x - want[i].x, found[i].y - want[i].y);
		sum += e;
		worst = std::max(worst, e);
	}
	std::printf("  plane: %zu corners, mean error %.3f px, max %.3f px\n", want.size(),
		    sum / double(want.size()), worst);
	assert_true(sum / double(want.size()) < 0.2);
	assert_true(worst < 0.5);

	// Independently of the prediction: OpenCV's chessboard detector finds the same corners.
	std::vector<cv::Point2f> sb;
	assert_true(cv::findChessboardCornersSB(gray, cv::Size(nx - 1, ny - 1), sb));
	double sb_worst = 0;
	for (const cv::Point2f &p : sb) {
		double best = 1e9;
		for (const cv::Point2d &w : want)
			best = std::min(best, std::hypot(p.x - w.x, p.y - w.y));
		sb_worst = std::max(sb_worst, best);
	}
	std::printf("  plane: findChessboardCornersSB max error %.3f px\n", sb_worst);
	assert_true(sb_worst < 0.5);
}

static void test_sphere_outline_lands_on_calibration(void **)
{
	const cv::Vec3d centre(25, -15, -30);
	const double radius = 70;
	Surface ball;
	ball.mesh = make_sphere(centre, radius, 256, 512);
	ball.id = 3;
	ball.albedo = cv::Vec3f(0.8f, 0.8f, 0.8f);
	Rig rig = test_rig(cv::Vec3d(120, 60, 480), cv::Vec3d(0, 0, 0));
	RenderOptions opt;
	opt.pattern = false;
	opt.noise = false;
	opt.truth = true;
	RenderResult res;
	assert_true(render_views(rig, {ball}, cv::Mat(), opt, 1, &res).ok());
	cv::Mat mask = res.truth[0].surface == 3;

	// The analytic outline: the circle of tangency seen from the camera centre, projected with
	// the forward model (cv::projectPoints, i.e. the distortion polynomial itself).
	const CameraModel &cm = rig.cameras[0].model;
	cv::Vec3d C = cm.centre(), axis = centre - C;
	double dist = cv::norm(axis);
	axis *= 1.0 / dist;
	double r_t = radius * std::sqrt(dist * dist - radius * radius) / dist; // tangency radius
	cv::Vec3d c_t = C + axis * ((dist * dist - radius * radius) / dist);
	cv::Vec3d u = cv::normalize(axis.cross(cv::Vec3d(0, 1, 0))), v = axis.cross(u);
	std::vector<cv::Point3d> rim;
	for (int k = 0; k < 4000; k++) {
		double a = 2 * kPi * k / 4000;
		rim.push_back(cv::Point3d(c_t + r_t * (std::cos(a) * u + std::sin(a) * v)));
	}
	cv::Vec3d rvec;
	cv::Rodrigues(cm.R, rvec);
	std::vector<cv::Point2d> outline;
	cv::projectPoints(rim, rvec, cm.T, cm.K, cm.dist, outline);
	std::vector<cv::Point2f> contour(outline.begin(), outline.end());

	// Every pixel centre farther than 0.5 px from the outline is on the right side of it.
	// (The mesh is a polygon: its chords lie inside the true sphere by r(1-cos(pi/512)).)
	int checked = 0, wrong = 0, band = 0;
	double worst_wrong = 0;
	for (int y = 0; y < mask.rows; y++)
		for (int x = 0; x < mask.cols; x++) {
			double d = cv::pointPolygonTest(contour, cv::Point2f(float(x), float(y)), true);
			if (std::fabs(d) > 4)
				continue;
			bool inside = mask.at<uint8_t>(y, x) != 0;
			if (std::fabs(d) <= 0.5) {
				band++;
				continue;
			}
			checked++;
			if (inside != (d > 0)) {
				wrong++;
				worst_wrong = std::max(worst_wrong, std::fabs(d));
			}
		}
	std::printf("  sphere: %d pixels near the outline checked, %d in the 0.5 px band, %d on the "
		    "wrong side (worst %.2f px)\n",
		    checked, band, wrong, worst_wrong);
	assert_true(checked > 1000);
	assert_int_equal(wrong, 0);
}

static void test_projector_shadow(void **)
{
	// A wall at z = 0, a ball in front of it, one projector throwing a white slide from the
	// upper left; the camera looks from the front right.
	Surface wall;
	wall.mesh = make_plane(600, 600, 2);
	wall.id = 1;
	wall.albedo = cv::Vec3f(0.7f, 0.7f, 0.7f);
	const cv::Vec3d ball_c(0, 0, 120);
	const double ball_r = 40;
	Surface ball;
	ball.mesh = make_sphere(ball_c, ball_r, 128, 256);
	ball.id = 2;
	Rig rig = test_rig(cv::Vec3d(150, 0, 700), cv::Vec3d(0, 0, 0));
	rig.cameras[0].model.dist = cv::Vec<double, 5>(0, 0, 0, 0, 0);
	rig.sensor.bayer = false;
	SimProjector pr;
	pr.K = cv::Matx33d(700, 0, 511.5, 0, 700, 383.5, 0, 0, 1);
	look_at(cv::Vec3d(-300, 250, 650), cv::Vec3d(0, 0, 0), 0, &pr.R, &pr.T);
	pr.power = 1.5;
	rig.projectors.push_back(pr);
	rig.lighting.ambient_pattern = 0.01;

	cv::Mat white(768, 1024, CV_8UC3, cv::Scalar(255, 255, 255));
	RenderOptions opt;
	opt.texture = false;
	opt.noise = false;
	opt.truth = true;
	RenderResult res;
	assert_true(render_views(rig, {wall, ball}, white, opt, 1, &res).ok());
	const ViewTruth &t = res.truth[0];
	cv::Mat gray;
	cv::cvtColor(res.frames[0], gray, cv::COLOR_BGR2GRAY);

	const CameraModel &cm = rig.cameras[0].model;
	const cv::Vec3d P = pr.centre();
	int shadow = 0, lit = 0, bad_truth = 0, bad_image = 0;
	double shadow_max = 0, lit_min = 255;
	for (int y = 0; y < 480; y += 2)
		for (int x = 0; x < 640; x += 2) {
			if (t.surface.at<uint8_t>(y, x) != 1)
				continue;
			cv::Vec3d o, d;
			pixel_ray(cm, cv::Point2d(x, y), &o, &d);
			cv::Vec3d w = o + d * (-o[2] / d[2]); // on the wall, z = 0
			// Distance from the ball's centre to the segment wall point → projector.
			cv::Vec3d s = P - w;
			double a = std::clamp((ball_c - w).dot(s) / s.dot(s), 0.0, 1.0);
			double m = cv::norm(w + a * s - ball_c);
			if (std::fabs(m - ball_r) < 2.5) // the penumbra of a polygonal ball + defocus
				continue;
			bool hidden = m < ball_r;
			bool truth_lit = t.projector.at<int8_t>(y, x) >= 0;
			int v = gray.at<uint8_t>(y, x);
			if (hidden) {
				shadow++;
				bad_truth += truth_lit;
				if (std::fabs(m - ball_r) > 6) {
					shadow_max = std::max(shadow_max, double(v));
					bad_image += v > 50;
				}
			} else {
				lit++;
				bad_truth += !truth_lit;
				if (std::fabs(m - ball_r) > 6) {
					lit_min = std::min(lit_min, double(v));
					bad_image += v < 80;
				}
			}
		}
	std::printf("  shadow: %d hidden and %d lit wall pixels; brightest hidden %.0f, darkest lit "
		    "%.0f; %d truth and %d image disagreements\n",
		    shadow, lit, shadow_max, lit_min, bad_truth, bad_image);
	assert_true(shadow > 300 && lit > 3000);
	assert_int_equal(bad_truth, 0);
	assert_int_equal(bad_image, 0);
}

static void test_same_seed_same_images(void **)
{
	Scene scene;
	assert_true(scene_by_name("default", &scene).ok());
	scene.head.cell_mm = 3.0; // a coarse head keeps the sanitizer build quick
	Rig rig = default_rig();
	assert_true(scale_rig(0.15, &rig).ok());
	Pattern pattern;
	assert_true(default_pattern(SlideSpec(), &pattern).ok());
	CaptureSet a, b, c;
	SimTruth ta;
	assert_true(simulate(rig, scene, pattern, 7, &a, &ta).ok());
	assert_true(simulate(rig, scene, pattern, 7, &b, nullptr).ok());
	assert_true(simulate(rig, scene, pattern, 8, &c, nullptr).ok());
	assert_int_equal(a.frames.size(), 4);
	assert_int_equal(a.textures.size(), 4);
	double diff_other = 0;
	for (size_t i = 0; i < 4; i++) {
		assert_int_equal(cv::norm(a.frames[i], b.frames[i], cv::NORM_INF), 0);
		assert_int_equal(cv::norm(a.textures[i], b.textures[i], cv::NORM_INF), 0);
		diff_other += cv::norm(a.frames[i], c.frames[i], cv::NORM_L1);
	}
	std::printf("  seed 7 twice: identical; seed 8 differs by %.0f (L1)\n", diff_other);
	assert_true(diff_other > 0);
	assert_string_equal(a.meta.pattern_id.c_str(), pattern.id.c_str());
	assert_int_equal(a.calibration.cameras.size(), 4);
	assert_true(a.frames[0].size() == rig.cameras[0].model.size);
	assert_true(ta.head.triangles.size() > 1000);
}

static void test_render_errors(void **)
{
	Surface s;
	s.mesh = make_plane(10, 10);
	RenderOptions opt;
	RenderResult res;
	Rig empty;
	assert_int_equal(render_views(empty, {s}, cv::Mat(), opt, 1, &res).code(), -EINVAL);
	Rig rig = default_rig();
	Status st = render_views(rig, {s}, cv::Mat(), opt, 1, &res);
	assert_int_equal(st.code(), -EINVAL); // pattern frames need a slide
	assert_non_null(std::strstr(st.message().c_str(), "slide"));
	assert_int_equal(render_views(rig, {}, cv::Mat(3, 3, CV_8UC3), opt, 1, &res).code(), -EINVAL);
	Surface broken = s;
	broken.mesh.triangles.push_back(cv::Vec3i(0, 1, 99));
	st = render_views(rig, {broken}, cv::Mat(8, 8, CV_8UC3), opt, 1, &res);
	assert_int_equal(st.code(), -EINVAL);
	assert_non_null(std::strstr(st.message().c_str(), "out of range"));
	opt.projectors_on = {true};
	assert_int_equal(render_views(rig, {s}, cv::Mat(8, 8, CV_8UC3), opt, 1, &res).code(), -EINVAL);
	Scene scene;
	st = scene_by_name("sideways", &scene);
	assert_int_equal(st.code(), -EINVAL);
	assert_non_null(std::strstr(st.message().c_str(), "turned"));
	Mesh m;
	HeadSpec hs;
	hs.cell_mm = 0.01;
	assert_int_equal(make_head(hs, cv::Vec3f(0.5f, 0.4f, 0.3f), &m).code(), -EINVAL);
}

// Number of edges not shared by exactly two triangles (0 = a closed 2-manifold); with
// `odd`, only those used by an odd number of triangles (boundary edges: holes).
static size_t open_edges(const Mesh &m, bool odd = false)
{
	std::vector<std::pair<int, int>> edges;
	for (const cv::Vec3i &t : m.triangles)
		for (int k = 0; k < 3; k++)
			edges.push_back({std::min(t[k], t[(k + 1) % 3]), std::max(t[k], t[(k + 1) % 3])});
	std::sort(edges.begin(), edges.end());
	size_t i = 0, bad = 0;
	while (i < edges.size()) {
		size_t j = i;
		while (j < edges.size() && edges[j] == edges[i])
			j++;
		bad += odd ? (j - i) % 2 : (j - i) != 2;
		i = j;
	}
	return bad;
}

// Largest distance from a vertex of `b` to the nearest vertex of `a` (mm; 3 mm hash cells,
// distances beyond 3 mm are reported as 3).
static double max_vertex_distance(const Mesh &a, const Mesh &b)
{
	auto key = [](const cv::Vec3f &v) {
		return std::make_tuple(int(std::floor(v[0] / 3)), int(std::floor(v[1] / 3)), int(std::floor(v[2] / 3)));
	};
	std::map<std::tuple<int, int, int>, std::vector<cv::Vec3f>> grid;
	for (const cv::Vec3f &v : a.vertices)
		grid[key(v)].push_back(v);
	double worst = 0;
	for (const cv::Vec3f &v : b.vertices) {
		auto [i, j, k] = key(v);
		double best = 3;
		for (int di = -1; di <= 1; di++)
			for (int dj = -1; dj <= 1; dj++)
				for (int dk = -1; dk <= 1; dk++) {
					auto it = grid.find({i + di, j + dj, k + dk});
					if (it == grid.end())
						continue;
					for (const cv::Vec3f &w : it->second)
						best = std::min(best, double(cv::norm(v - w)));
				}
		worst = std::max(worst, best);
	}
	return worst;
}

static void test_head_variation(void **)
{
	// Every drawn parameter lies in its documented range, and the draws spread over it.
	const auto &ranges = head_shape_ranges();
	assert_int_equal(ranges.size(), 14);
	std::vector<double> lo(ranges.size(), 1e9), hi(ranges.size(), -1e9);
	HeadShape canonical;
	for (uint64_t seed = 0; seed < 300; seed++) {
		HeadShape h = random_head_shape(seed);
		for (size_t r = 0; r < ranges.size(); r++) {
			double v = h.*ranges[r].member;
			assert_true(v >= ranges[r].lo && v <= ranges[r].hi);
			lo[r] = std::min(lo[r], v);
			hi[r] = std::max(hi[r], v);
		}
	}
	for (size_t r = 0; r < ranges.size(); r++) {
		double c = canonical.*ranges[r].member;
		assert_true(c > ranges[r].lo && c < ranges[r].hi); // the canonical head is inside
		assert_true(hi[r] - lo[r] > 0.8 * (ranges[r].hi - ranges[r].lo));
		// Factors stay within 15 % of the canonical head.
		if (c == 1)
			assert_true(ranges[r].lo >= 0.85 && ranges[r].hi <= 1.15);
	}
	// Out of range is refused, naming the parameter.
	HeadSpec spec;
	spec.cell_mm = 3.0; // a coarse head keeps the sanitizer build quick
	spec.shape.nose_length = 1.5;
	Mesh m;
	Status st = make_head(spec, cv::Vec3f(0.6f, 0.4f, 0.3f), &m);
	assert_int_equal(st.code(), -EINVAL);
	assert_non_null(std::strstr(st.message().c_str(), "nose_length"));

	// Same head seed: identical meshes; other head seeds: a different head, still closed.
	Mesh h0, h1a, h1b, h2;
	assert_true(make_head(HeadSpec{2.0, 1, HeadShape(), HeadLook(), ""}, cv::Vec3f(0.6f, 0.4f, 0.3f), &h0).ok());
	assert_true(make_head(HeadSpec{2.0, 1, random_head_shape(1), HeadLook(), ""}, cv::Vec3f(0.6f, 0.4f, 0.3f), &h1a).ok());
	assert_true(make_head(HeadSpec{2.0, 1, random_head_shape(1), HeadLook(), ""}, cv::Vec3f(0.6f, 0.4f, 0.3f), &h1b).ok());
	assert_true(make_head(HeadSpec{2.0, 1, random_head_shape(2), HeadLook(), ""}, cv::Vec3f(0.6f, 0.4f, 0.3f), &h2).ok());
	assert_int_equal(h1a.vertices.size(), h1b.vertices.size());
	assert_int_equal(h1a.triangles.size(), h1b.triangles.size());
	for (size_t i = 0; i < h1a.vertices.size(); i++)
		assert_true(h1a.vertices[i] == h1b.vertices[i]);
	for (size_t i = 0; i < h1a.triangles.size(); i++)
		assert_true(h1a.triangles[i] == h1b.triangles[i]);
	double d12 = max_vertex_distance(h1a, h2), d21 = max_vertex_distance(h2, h1a);
	double d01 = max_vertex_distance(h0, h1a);
	std::printf("  head seeds 1 vs 2: max vertex distance %.1f / %.1f mm; canonical vs seed 1: %.1f mm\n",
		    d12, d21, d01);
	assert_true(std::max(d12, d21) > 1.0);
	assert_true(d01 > 1.0);
	for (const Mesh *h : {&h0, &h1a, &h2}) {
		cv::Vec3f blo(1e9f, 1e9f, 1e9f), bhi(-1e9f, -1e9f, -1e9f);
		for (const cv::Vec3f &v : h->vertices)
			for (int k = 0; k < 3; k++) {
				blo[k] = std::min(blo[k], v[k]);
				bhi[k] = std::max(bhi[k], v[k]);
			}
		size_t holes = open_edges(*h, true), non_manifold = open_edges(*h);
		std::printf("  head: %zu triangles, x %.0f..%.0f, y %.0f..%.0f, z %.0f..%.0f mm, %zu edges "
			    "not shared by 2 triangles (%zu boundary)\n",
			    h->triangles.size(), blo[0], bhi[0], blo[1], bhi[1], blo[2], bhi[2], non_manifold, holes);
		// Watertight: no boundary edge. Surface nets may join two sheets at an ambiguous grid
		// face (an edge of 4 triangles); the canonical head has none (test_head_anatomy), a
		// varied head a handful at most (docs/simulator.md).
		assert_int_equal(holes, 0);
		assert_true(non_manifold <= 10);
		if (h == &h0)
			assert_int_equal(non_manifold, 0);
		// Still an adult head: ears at about +-70..100, crown above, nose tip in front.
		assert_true(bhi[0] > 65 && bhi[0] < 105 && blo[0] < -65 && blo[0] > -105);
		assert_true(bhi[1] > 95 && bhi[1] < 150);
		assert_true(bhi[2] > 95 && bhi[2] < 140);
	}
}

static void test_head_anatomy(void **)
{
	Mesh m;
	HeadSpec hs;
	hs.cell_mm = 2.0;
	assert_true(make_head(hs, cv::Vec3f(0.6f, 0.4f, 0.3f), &m).ok());
	cv::Vec3f lo(1e9f, 1e9f, 1e9f), hi(-1e9f, -1e9f, -1e9f);
	for (const cv::Vec3f &v : m.vertices)
		for (int k = 0; k < 3; k++) {
			lo[k] = std::min(lo[k], v[k]);
			hi[k] = std::max(hi[k], v[k]);
		}
	std::printf("  head: %zu triangles, x %.0f..%.0f, y %.0f..%.0f, z %.0f..%.0f mm\n",
		    m.triangles.size(), lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]);
	// Adult proportions: ears at about +-80, crown ~120 above the eyes, nose tip in front.
	assert_true(hi[0] > 70 && hi[0] < 100 && lo[0] < -70 && lo[0] > -100);
	assert_true(hi[1] > 100 && hi[1] < 140);
	assert_true(hi[2] > 100 && hi[2] < 125); // the nose tip is the front-most point
	// Every edge is shared by exactly two triangles: a closed surface.
	size_t bad = open_edges(m);
	std::printf("  head: %zu edges not shared by exactly 2 triangles\n", bad);
	assert_int_equal(bad, 0);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_plane_corners_land_on_calibration),
		cmocka_unit_test(test_sphere_outline_lands_on_calibration),
		cmocka_unit_test(test_projector_shadow),
		cmocka_unit_test(test_same_seed_same_images),
		cmocka_unit_test(test_render_errors),
		cmocka_unit_test(test_head_anatomy),
		cmocka_unit_test(test_head_variation),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
