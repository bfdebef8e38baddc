// Stage D (dense matching) and the dense surface fusion, on inputs with known answers: a
// rectification that reprojects exactly, a disparity prior that is linear inside its triangles,
// a sphere rendered by the simulator under the pattern (dense points must lie on it), the coarse
// search with no code at all, and the fusion of two offset sheets into one.
#include "pattern/pattern.hpp"
#include "recon/dense.hpp"
#include "recon/surface.hpp"
#include "recon/triangulate.hpp"
#include "sim/sim.hpp"
#include "synthetic_rig.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "cmocka.hpp"

using namespace facescan;
using namespace facescan::recon;

namespace {

// A point seen by both cameras of a pair comes back from its rectified disparity.
void rectification_reprojects_exactly(void **)
{
	const std::vector<CameraModel> cams = synth::ring();
	for (int p = 0; p < 3; ++p) {
		RectifiedPair rp;
		assert_true(rectify_pair(cams[size_t(p)], cams[size_t(p + 1)], 0.5, &rp).ok());
		for (const cv::Point3d &w : {cv::Point3d(0, 0, 60), cv::Point3d(-40, 50, 20), cv::Point3d(35, -60, 40)}) {
			const cv::Point2d pa = project_points(cams[size_t(p)], {w})[0];
			const cv::Point2d pb = project_points(cams[size_t(p + 1)], {w})[0];
			const cv::Point2d ra = rectify_points(rp, cams[size_t(p)], 0, {pa})[0];
			const cv::Point2d rb = rectify_points(rp, cams[size_t(p + 1)], 1, {pb})[0];
			assert_true(std::fabs(ra.y - rb.y) < 1e-6);		// rows agree
			assert_true(ra.x > 0 && ra.x < rp.size.width && ra.y > 0 && ra.y < rp.size.height);
			const cv::Point3d back = rectified_to_world(rp, cams[size_t(p)], ra.x, ra.y, ra.x - rb.x);
			assert_true(cv::norm(back - w) < 1e-6);
		}
	}
	RectifiedPair rp;
	assert_int_equal(rectify_pair(cams[0], cams[0], 0.5, &rp).code(), -EINVAL); // no baseline
}

// A camera at `centre` looking at the origin, rolled by `roll_deg` about its optical axis.
CameraModel camera_looking_from(const cv::Vec3d &centre, double roll_deg)
{
	CameraModel cam = synth::camera_at(0);
	const cv::Vec3d z = -centre * (1.0 / cv::norm(centre));
	cv::Vec3d x = cv::Vec3d(0, 1, 0).cross(z);
	x *= 1.0 / cv::norm(x);
	const cv::Vec3d y = z.cross(x);
	const double r = roll_deg * CV_PI / 180;
	const cv::Vec3d xr = std::cos(r) * x + std::sin(r) * y, yr = -std::sin(r) * x + std::cos(r) * y;
	cam.R = cv::Matx33d(xr[0], xr[1], xr[2], yr[0], yr[1], yr[2], z[0], z[1], z[2]);
	cam.T = -(cam.R * centre);
	return cam;
}

// Random booth 204's pair 2-3: b 45 degrees down and to the right of a, converging by 29 degrees,
// both cameras rolled. stereoRectify put that baseline on the y axis (the pair failed); it must
// rectify along x, b to the right, and reproject exactly. So must a pair whose b is to the left.
void rectification_keeps_diagonal_baselines_on_x(void **)
{
	const CameraModel a = camera_looking_from(cv::Vec3d(-40, 90, 540), 8);
	const CameraModel b = camera_looking_from(cv::Vec3d(110, -90, 500), -10); // y up: b is lower
	for (int flip = 0; flip < 2; ++flip) {
		const CameraModel &ca = flip ? b : a, &cb = flip ? a : b;
		RectifiedPair rp;
		const Status s = rectify_pair(ca, cb, 0.5, &rp);
		if (!s.ok())
			std::printf("rectify_pair: %s\n", s.message().c_str());
		assert_true(s.ok());
		assert_true(rp.baseline > 0); // b to the right: disparities positive
		const cv::Vec3d cb_rect = rp.R1 * (ca.R * (cb.centre() - ca.centre()));
		assert_true(std::fabs(cb_rect[1]) + std::fabs(cb_rect[2]) < 1e-6 * cv::norm(cb_rect));
		for (const cv::Point3d &w : {cv::Point3d(0, 0, 60), cv::Point3d(-40, 50, 20), cv::Point3d(35, -60, 40)}) {
			const cv::Point2d ra = rectify_points(rp, ca, 0, {project_points(ca, {w})[0]})[0];
			const cv::Point2d rb = rectify_points(rp, cb, 1, {project_points(cb, {w})[0]})[0];
			assert_true(std::fabs(ra.y - rb.y) < 1e-6);
			assert_true(ra.x > 0 && ra.x < rp.size.width && ra.y > 0 && ra.y < rp.size.height);
			assert_true(cv::norm(rectified_to_world(rp, ca, ra.x, ra.y, ra.x - rb.x) - w) < 1e-6);
		}
	}
}

// Inside a seed triangle the prior is the plane through its vertices; past the rim the nearest
// value reaches as far as asked and no farther.
void prior_is_linear_in_its_triangles(void **)
{
	std::vector<cv::Point2d> seeds;
	std::vector<double> d;
	auto plane = [](double x, double y) { return 10 + 0.05 * x - 0.02 * y; };
	for (int y = 20; y <= 180; y += 20)
		for (int x = 20; x <= 180; x += 20) {
			seeds.emplace_back(x, y);
			d.push_back(plane(x, y));
		}
	double spacing = 0;
	const cv::Mat prior = disparity_prior(cv::Size(260, 200), seeds, d, 4.0, 1.0, &spacing);
	assert_true(std::fabs(spacing - 20) < 1e-6);
	double worst = 0;
	for (int y = 20; y <= 180; ++y)
		for (int x = 20; x <= 180; ++x)
			worst = std::max(worst, std::fabs(prior.at<float>(y, x) - plane(x, y)));
	assert_true(worst < 1e-3);
	assert_true(prior.at<float>(100, 195) == prior.at<float>(100, 195));	// within one spacing
	assert_true(std::fabs(prior.at<float>(100, 195) - plane(180, 100)) < 1e-3); // nearest value
	assert_true(prior.at<float>(100, 230) != prior.at<float>(100, 230));	// beyond: none
	// Fewer than three seeds: no prior at all.
	const cv::Mat none = disparity_prior(cv::Size(50, 50), {{10, 10}, {20, 20}}, {1, 2}, 4, 1, nullptr);
	assert_int_equal(cv::countNonZero(has_value(none)), 0);
}

struct SphereScene {
	std::vector<CameraModel> cams;
	std::vector<cv::Mat> frames;
	cv::Vec3d centre{0, -10, 10};
	double radius = 85;
};

// The default booth at half resolution throwing the default pattern onto a sphere.
void render_sphere(SphereScene *scene)
{
	sim::Rig rig = sim::default_rig();
	assert_true(sim::scale_rig(0.5, &rig).ok());
	Pattern pattern;
	assert_true(default_pattern(SlideSpec(), &pattern).ok());
	sim::Surface ball;
	ball.mesh = sim::make_sphere(scene->centre, scene->radius, 192, 384);
	ball.albedo = cv::Vec3f(0.6f, 0.45f, 0.38f);
	sim::RenderOptions opt;
	opt.texture = false;
	sim::RenderResult res;
	assert_true(sim::render_views(rig, {ball}, render_slide(pattern), opt, 7, &res).ok());
	scene->frames = res.frames;
	for (const sim::SimCamera &d : rig.cameras)
		scene->cams.push_back(d.model);
}

// Exact code matches on a grid of sphere points both cameras see (what the sparse stage gives).
PartialModel sphere_seeds(const SphereScene &s, int a, int b, double step_deg)
{
	PartialModel model;
	model.cam_a = a;
	model.cam_b = b;
	for (double el = -60; el <= 60; el += step_deg)
		for (double az = -80; az <= 80; az += step_deg) {
			const double e = el * CV_PI / 180, z = az * CV_PI / 180;
			const cv::Vec3d n(std::cos(e) * std::sin(z), std::sin(e), std::cos(e) * std::cos(z));
			const cv::Point3d p(s.centre + n * s.radius);
			if (!synth::sees(s.cams[size_t(a)], p, n) || !synth::sees(s.cams[size_t(b)], p, n))
				continue;
			PointMatch m;
			m.a = project_points(s.cams[size_t(a)], {p})[0];
			m.b = project_points(s.cams[size_t(b)], {p})[0];
			model.points.push_back(p);
			model.sources.push_back(m);
		}
	return model;
}

struct Errors {
	double median = 0, p95 = 0;
	size_t n = 0;
};

Errors sphere_errors(const SphereScene &s, const DenseCloud &cloud)
{
	std::vector<double> e;
	for (const cv::Point3f &p : cloud.points)
		e.push_back(std::fabs(cv::norm(cv::Vec3d(p.x, p.y, p.z) - s.centre) - s.radius));
	Errors r;
	r.n = e.size();
	if (e.empty())
		return r;
	std::sort(e.begin(), e.end());
	r.median = e[e.size() / 2];
	r.p95 = e[e.size() * 95 / 100];
	return r;
}

void dense_points_lie_on_the_sphere(void **)
{
	SphereScene s;
	render_sphere(&s);
	const PartialModel seeds = sphere_seeds(s, 1, 2, 4);
	assert_true(seeds.sources.size() > 100);
	// The scene is rendered at half the booth's resolution; matching at its full resolution is
	// the booth's default matching resolution.
	DenseParams params;
	params.scale = 1.0;
	DenseCloud cloud;
	DenseStats stats;
	assert_true(dense_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], seeds, params, &cloud, &stats).ok());
	const Errors e = sphere_errors(s, cloud);
	std::printf("dense on a sphere: %zu points from %d seeds, median %.3f mm, p95 %.3f mm\n", e.n, stats.seeds,
		    e.median, e.p95);
	// The cameras see ~15k pixels of the sphere at the matching resolution (a quarter of
	// 1600x1200); far more points than seeds, each within a fraction of a millimetre.
	assert_true(e.n > 20 * seeds.sources.size());
	// Measured 0.097 / 0.48 mm (before fusion, which averages the pairs): a margin of ~30 %.
	assert_true(e.median < 0.13);
	assert_true(e.p95 < 0.65);
	assert_int_equal(cloud.points.size(), cloud.confidence.size());
	assert_int_equal(cloud.points.size(), cloud.border_mm.size());
	// One point per matching pixel instead of one per camera pixel the refinement measured: the
	// same surface from fewer points, none of the others interpolated, so no more accurate.
	DenseParams coarse = params;
	coarse.points_at_refine_scale = false;
	DenseCloud one;
	assert_true(dense_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], seeds, coarse, &one, nullptr).ok());
	const Errors e1 = sphere_errors(s, one);
	std::printf("dense on a sphere, one point per matching pixel: %zu points, median %.3f mm, p95 %.3f mm\n",
		    e1.n, e1.median, e1.p95);
	assert_true(e.n > 2 * e1.n && e.n <= 4 * e1.n);
	assert_true(e.median < 1.1 * e1.median);
	assert_true(e.p95 < 1.1 * e1.p95);
}

// The sphere's middle pair with no code at all: the coarse search alone gives the prior.
bool unseeded_pair(const SphereScene &s, const DenseParams &params, DenseCloud *ret_cloud, DenseStats *ret_stats)
{
	PartialModel none;
	none.cam_a = 1;
	none.cam_b = 2;
	return dense_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], none, params, ret_cloud, ret_stats).ok();
}

// With no code at all the coarse search over the working volume still finds the sphere.
void coarse_search_works_without_code(void **)
{
	SphereScene s;
	render_sphere(&s);
	DenseParams params;
	params.scale = 1.0;
	DenseCloud cloud;
	DenseStats stats;
	assert_true(unseeded_pair(s, params, &cloud, &stats));
	const Errors e = sphere_errors(s, cloud);
	std::printf("dense without code: %zu points, coarse prior on %d px, median %.3f mm, p95 %.3f mm\n", e.n,
		    stats.coarse_pixels, e.median, e.p95);
	assert_int_equal(stats.seeds, 0);
	assert_true(stats.coarse_pixels > 0);
	// Measured 28k points, 0.15 / 0.93 mm: the code's prior is the better one, as it should be.
	assert_true(e.n > 10000);
	assert_true(e.median < 0.2);
	assert_true(e.p95 < 1.3);
	// The coarse search runs on the bounding box of the lit pixels the code misses (plus a
	// margin), not the whole frame: the frame-wide search finds the same surface.
	DenseParams whole = params;
	whole.coarse_margin_px = 100000;
	DenseCloud cloud_whole;
	DenseStats stats_whole;
	assert_true(unseeded_pair(s, whole, &cloud_whole, &stats_whole));
	const Errors ew = sphere_errors(s, cloud_whole);
	std::printf("coarse over the whole frame: %zu points, coarse prior on %d px, median %.3f mm, p95 %.3f mm\n",
		    ew.n, stats_whole.coarse_pixels, ew.median, ew.p95);
	assert_true(std::fabs(double(e.n) - double(ew.n)) < 0.02 * double(ew.n));
	assert_true(std::fabs(e.median - ew.median) < 0.01);
	assert_true(std::fabs(e.p95 - ew.p95) < 0.05);
	// Without the coarse search and without code there is nothing to match.
	DenseParams off = params;
	off.coarse = false;
	assert_true(unseeded_pair(s, off, &cloud, &stats));
	assert_int_equal(cloud.points.size(), 0);
}

// Seeds from one small patch of the sphere (a pair that decodes only a corner of the face): their
// disparities span a sliver of the sphere's, so a coarse search over their range alone finds
// little of the rest; with the patch's triangles covering under `min_seed_cover` of the lit
// pixels it spans the working volume's disparities too, and finds the sphere.
void coarse_search_spans_the_volume_when_seeds_cluster(void **)
{
	SphereScene s;
	render_sphere(&s);
	const PartialModel all = sphere_seeds(s, 1, 2, 2);
	// The patch: the seeds nearest the sphere's lit top (7 x 7 degrees of it).
	cv::Point3d top(0, 1e9, 0);
	for (const cv::Point3d &p : all.points)
		if (p.y < top.y)
			top = p;
	PartialModel patch;
	patch.cam_a = all.cam_a;
	patch.cam_b = all.cam_b;
	for (size_t i = 0; i < all.points.size(); ++i)
		if (cv::norm(all.points[i] - top) < 10) {
			patch.points.push_back(all.points[i]);
			patch.sources.push_back(all.sources[i]);
		}
	assert_true(patch.points.size() >= 6);
	DenseParams params;
	params.scale = 1.0;
	DenseParams seeds_only = params;
	seeds_only.min_seed_cover = 0;
	DenseCloud cloud, cloud_seeds;
	DenseStats stats, stats_seeds;
	assert_true(dense_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], patch, params, &cloud, &stats).ok());
	assert_true(dense_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], patch, seeds_only, &cloud_seeds,
			       &stats_seeds)
			    .ok());
	const Errors e = sphere_errors(s, cloud), es = sphere_errors(s, cloud_seeds);
	std::printf("%d clustered seeds covering %.1f %% of the lit pixels: %zu points over the volume's range, "
		    "median %.3f mm (the seeds' range only: %zu points, median %.3f mm)\n",
		    stats.seeds, 100 * stats.seed_cover, e.n, e.median, es.n, es.median);
	assert_true(stats.seed_cover > 0 && stats.seed_cover < params.min_seed_cover);
	assert_true(stats.coarse_over_volume);
	assert_false(stats_seeds.coarse_over_volume);
	assert_true(double(e.n) > 1.5 * double(es.n));
	assert_true(e.median < 0.2);
	// Seeds all over the sphere cover it: their own range, as before.
	DenseCloud spread;
	DenseStats stats_spread;
	assert_true(dense_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], all, params, &spread, &stats_spread).ok());
	assert_true(stats_spread.seed_cover > params.min_seed_cover);
	assert_false(stats_spread.coarse_over_volume);
}

// Points of the sphere `out_mm` beyond its surface, every degree of elevation within ±`el_max` and
// of azimuth from `az_from` up to `az_to` (excluded): a guide made of other pairs' points.
static std::vector<cv::Point3f> sphere_grid(const SphereScene &s, double el_max, double az_from, double az_to,
					    double out_mm)
{
	std::vector<cv::Point3f> points;
	for (double el = -el_max; el <= el_max; el += 1)
		for (double az = az_from; az < az_to; az += 1) {
			const double e = el * CV_PI / 180, z = az * CV_PI / 180;
			const cv::Vec3d n(std::cos(e) * std::sin(z), std::sin(e), std::cos(e) * std::cos(z));
			points.emplace_back(cv::Vec3f(s.centre + n * (s.radius + out_mm)));
		}
	return points;
}

// A pair with no code and no coarse search is guided by other pairs' points alone: points all
// over the sphere, its back half too (what the left camera cannot see: the nearest point of each
// cell wins) and 1 mm too far out (a neighbour's error: the residual search takes it up), give a
// prior on which the pair matches the sphere itself.
void guide_points_give_the_prior(void **)
{
	SphereScene s;
	render_sphere(&s);
	const std::vector<cv::Point3f> guide = sphere_grid(s, 88, -180, 180, 1.0);
	DenseParams params;
	params.scale = 1.0;
	params.coarse = false;
	DenseCloud cloud;
	DenseStats stats;
	assert_true(unseeded_pair(s, params, &cloud, &stats));
	assert_int_equal(cloud.points.size(), 0); // nothing to match without a prior
	PartialModel none;
	none.cam_a = 1;
	none.cam_b = 2;
	assert_true(dense_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], none, params, &cloud, &stats, nullptr,
			       &guide)
			    .ok());
	const Errors e = sphere_errors(s, cloud);
	std::printf("dense guided by the sphere's points 1 mm out: %zu points, guided prior on %d px, median %.3f mm, "
		    "p95 %.3f mm\n",
		    e.n, stats.guided_pixels, e.median, e.p95);
	assert_int_equal(stats.coarse_pixels, 0);
	assert_true(stats.guided_pixels > 0);
	// Measured 137k points, 0.082 / 0.323 mm: what the code's seeds give (138k, 0.072 / 0.328),
	// more and closer than the coarse search (78k, 0.121 / 0.516); the 1 mm is not in them.
	assert_true(e.n > 100000);
	assert_true(e.median < 0.11);
	assert_true(e.p95 < 0.45);
}

// The guided pass matches each pair again from its preparation: a match must leave the prepared
// pair as it found it (a match after a guided one is the first match again), and prepare + match
// must be what dense_pair gives in one call.
void prepared_pair_matches_again_unchanged(void **)
{
	SphereScene s;
	render_sphere(&s);
	const PartialModel seeds = sphere_seeds(s, 1, 2, 4);
	const std::vector<cv::Point3f> guide = sphere_grid(s, 60, -90, 91, 0);
	DenseParams params;
	params.scale = 1.0;
	PreparedPair pp;
	assert_true(prepare_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], seeds, params, &pp).ok());
	DenseCloud first, guided, again, one_call;
	DenseStats first_stats, guided_stats;
	assert_true(match_pair(pp, nullptr, &first, &first_stats).ok());
	assert_true(match_pair(pp, &guide, &guided, &guided_stats).ok());
	assert_true(match_pair(pp, nullptr, &again, nullptr).ok());
	assert_true(dense_pair(s.frames[1], s.frames[2], s.cams[1], s.cams[2], seeds, params, &one_call, nullptr, nullptr,
			       &guide)
			    .ok());
	auto same = [](const DenseCloud &x, const DenseCloud &y) {
		if (x.points.size() != y.points.size() || x.confidence != y.confidence || x.border_mm != y.border_mm)
			return false;
		for (size_t i = 0; i < x.points.size(); ++i)
			if (x.points[i] != y.points[i])
				return false;
		return true;
	};
	std::printf("prepared pair: first match %zu points, guided %zu (guided prior on %d px), first again %zu, "
		    "dense_pair with the guide %zu\n",
		    first.points.size(), guided.points.size(), guided_stats.guided_pixels, again.points.size(),
		    one_call.points.size());
	assert_true(first.points.size() > 10000);
	assert_true(guided_stats.guided_pixels > 0);
	assert_int_equal(first_stats.guided_pixels, 0);
	assert_true(same(first, again));
	assert_true(same(guided, one_call));
}

// Matches next to a pixel SGBM refused are unsure (a mismatch or an occlusion beside them): with
// the margin off, the unseeded sphere keeps them and its tail of errors grows (measured p95 0.560
// against 0.550 mm with SGBM's 3 px block and the 1 px margin; 0.60 against 0.53 with the 5 px
// block and 2 px margin before 2026-12-06, whose wider windows smeared more across a refusal);
// with it on they go, and are counted. Judged on one point per matching pixel, the pixels the
// margin decides on (with the refinement's camera-pixel points as well, 0.505 against 0.510 mm:
// the points the margin keeps are more, and as good, as the ones it drops).
void matches_beside_refused_pixels_dropped(void **)
{
	SphereScene s;
	render_sphere(&s);
	DenseParams params;
	params.scale = 1.0;
	params.points_at_refine_scale = false;
	DenseParams off = params;
	off.unmatched_margin_px = 0;
	DenseCloud cloud, cloud_off;
	DenseStats stats, stats_off;
	assert_true(unseeded_pair(s, params, &cloud, &stats));
	assert_true(unseeded_pair(s, off, &cloud_off, &stats_off));
	const Errors e = sphere_errors(s, cloud), eo = sphere_errors(s, cloud_off);
	std::printf("beside refused pixels: %d dropped; p95 %.3f mm (off: %.3f mm, %zu against %zu points)\n",
		    stats.near_unmatched, e.p95, eo.p95, e.n, eo.n);
	assert_int_equal(stats_off.near_unmatched, 0);
	assert_true(stats.near_unmatched > 0);
	assert_true(e.n < eo.n);
	assert_true(e.p95 < eo.p95 - 0.005);
}

void dense_refuses_bad_input(void **)
{
	const std::vector<CameraModel> cams = synth::ring();
	DenseCloud cloud;
	PartialModel model;
	cv::Mat grey(600, 800, CV_8UC1, cv::Scalar(0)), colour(600, 800, CV_8UC3, cv::Scalar(0));
	assert_int_equal(dense_pair(grey, colour, cams[0], cams[1], model, DenseParams(), &cloud, nullptr).code(), -EINVAL);
	DenseParams even;
	even.block = 4;
	assert_int_equal(dense_pair(colour, colour, cams[0], cams[1], model, even, &cloud, nullptr).code(), -EINVAL);
}

// Two clouds of one sphere cap, 0.3 mm apart in radius, overlapping in the middle: one sheet,
// merged where they overlap, at their weighted mean, with no crack and no second layer.
void fusion_makes_one_sheet(void **)
{
	const std::vector<CameraModel> cams = synth::ring();
	const cv::Vec3d c(0, 0, 0);
	const double R = 90;
	std::vector<DenseCloud> clouds(2);
	for (int k = 0; k < 2; ++k) {
		const double r = R + (k == 0 ? -0.15 : 0.15);
		for (double el = -40; el <= 40; el += 0.25)
			for (double az = (k == 0 ? -50 : -10); az <= (k == 0 ? 10 : 50); az += 0.25) {
				const double e = el * CV_PI / 180, z = az * CV_PI / 180;
				const cv::Vec3d n(std::cos(e) * std::sin(z), std::sin(e), std::cos(e) * std::cos(z));
				clouds[size_t(k)].points.emplace_back(cv::Point3d(c + n * r));
				clouds[size_t(k)].confidence.push_back(1.f);
				// Distance to the cloud's own border along the sphere, mm.
				const double edge = std::min({az - (k == 0 ? -50 : -10), (k == 0 ? 10 : 50) - az, el + 40, 40 - el});
				clouds[size_t(k)].border_mm.push_back(float(edge * CV_PI / 180 * R));
			}
	}
	Mesh mesh;
	SurfaceStats stats;
	assert_true(fuse_dense(clouds, {}, cams, SurfaceParams(), &mesh, &stats).ok());
	std::printf("fusion: %d vertices, %d triangles, %d merged cells, spacing %.2f mm\n", stats.vertices,
		    stats.triangles, stats.merged, stats.spacing_mm);
	assert_true(stats.merged > 1000);
	double worst = 0, overlap_worst = 0;
	for (const cv::Point3f &p : mesh.positions) {
		const double r = cv::norm(cv::Vec3d(p.x, p.y, p.z) - c);
		worst = std::max(worst, std::fabs(r - R));
		const double az = std::atan2(p.x, p.z) * 180 / CV_PI;
		if (az > -5 && az < 5) // far from both borders: equal weights, the mean
			overlap_worst = std::max(overlap_worst, std::fabs(r - R));
	}
	assert_true(worst < 0.16);
	assert_true(overlap_worst < 0.05);
	// One sheet: about one vertex per grid cell over the union (no second layer), and every
	// vertex in some triangle with (nearly) two triangles per vertex (no cracks inside).
	assert_true(mesh.triangles.size() > 1.9 * mesh.positions.size() - 4000);
	assert_true(double(stats.vertices) < 1.05 * double(stats.cells));
	// Nothing to fuse is an error, not a crash; so is a weight floor of 0 (every empty cell
	// would be a vertex at 0 / 0: it crashed before 2026-12-07).
	assert_int_equal(fuse_dense({}, {}, cams, SurfaceParams(), &mesh, &stats).code(), -ENODATA);
	SurfaceParams no_floor;
	no_floor.min_weight = 0;
	assert_int_equal(fuse_dense(clouds, {}, cams, no_floor, &mesh, &stats).code(), -EINVAL);
}

// A sphere cap with a hole of about 4 x 4 cells in its middle: trimming takes about one cell off
// the outline and nothing around the hole.
void fusion_trims_the_outline_not_the_holes(void **)
{
	const std::vector<CameraModel> cams = synth::ring();
	const double R = 90, deg = CV_PI / 180;
	std::vector<DenseCloud> clouds(1);
	for (double el = -20; el <= 20; el += 0.1)
		for (double az = -20; az <= 20; az += 0.1) {
			if (std::fabs(az) < 0.6 && std::fabs(el) < 0.6)
				continue; // the hole: 1.9 mm across, the grid's 0.35 mm cells
			const cv::Vec3d n(std::cos(el * deg) * std::sin(az * deg), std::sin(el * deg),
					  std::cos(el * deg) * std::cos(az * deg));
			clouds[0].points.emplace_back(cv::Point3d(n * R));
			clouds[0].confidence.push_back(1.f);
			clouds[0].border_mm.push_back(float(std::min(20 - std::fabs(az), 20 - std::fabs(el)) * deg * R));
		}
	// What each mesh covers: its extent in azimuth and how many vertices lie near the hole.
	auto fuse = [&](int trim, double *ret_min_az, int *ret_near_hole, SurfaceStats *ret_stats) {
		SurfaceParams params;
		params.trim_border_cells = trim;
		Mesh mesh;
		assert_true(fuse_dense(clouds, {}, cams, params, &mesh, ret_stats).ok());
		*ret_min_az = 1e9;
		*ret_near_hole = 0;
		for (const cv::Point3f &p : mesh.positions) {
			const double az = std::atan2(p.x, p.z) / deg, el = std::asin(p.y / cv::norm(p)) / deg;
			*ret_min_az = std::min(*ret_min_az, az);
			*ret_near_hole += std::fabs(az) < 1.5 && std::fabs(el) < 1.5;
		}
	};
	double az0 = 0, az1 = 0;
	int near0 = 0, near1 = 0;
	SurfaceStats s0, s1;
	fuse(0, &az0, &near0, &s0);
	fuse(1, &az1, &near1, &s1);
	const double cell_deg = s1.spacing_mm / R / deg;
	std::printf("trim: %d cells off the outline, %d -> %d vertices; edge %.3f -> %.3f deg (cell %.3f); "
		    "%d -> %d vertices near the hole\n",
		    s1.trimmed, s0.vertices, s1.vertices, az0, az1, cell_deg, near0, near1);
	assert_int_equal(s0.trimmed, 0);
	assert_true(s1.trimmed > 0);
	assert_int_equal(s0.vertices - s1.vertices, s1.trimmed);
	// One cell off the outline: the edge moves in by about one cell, and the trimmed cells are
	// about one ring around the 40 x 40 degree cap.
	assert_true(az1 - az0 > 0.5 * cell_deg && az1 - az0 < 1.5 * cell_deg);
	const double ring = 4 * 40 / cell_deg;
	assert_true(s1.trimmed > 0.7 * ring && s1.trimmed < 1.3 * ring);
	// The hole is not widened.
	assert_true(near0 > 0);
	assert_int_equal(near1, near0);
}

// A sphere cap with spikes (single matches 1.6 mm out, stronger than their neighbours, so each
// takes its cells; near enough to stay joined to them by triangles) and a 3 mm step across its
// middle: the median test drops the spikes' cells and keeps both sides of the step, whose cells
// mostly agree with their own side.
void fusion_drops_spikes_keeps_steps(void **)
{
	const std::vector<CameraModel> cams = synth::ring();
	const double R = 90, deg = CV_PI / 180;
	std::vector<DenseCloud> clouds(1);
	int spikes = 0;
	for (double el = -15; el <= 15; el += 0.1)
		for (double az = -15; az <= 15; az += 0.1) {
			const bool spike = std::fabs(std::fmod(el + 15, 6.0) - 3) < 0.05 &&
					   std::fabs(std::fmod(az + 15, 6.0) - 3) < 0.05 && std::fabs(az) > 2;
			const double r = R + (az > 0 ? 3 : 0) + (spike ? 1.6 : 0);
			spikes += spike;
			const cv::Vec3d n(std::cos(el * deg) * std::sin(az * deg), std::sin(el * deg),
					  std::cos(el * deg) * std::cos(az * deg));
			clouds[0].points.emplace_back(cv::Point3d(n * r));
			clouds[0].confidence.push_back(spike ? 1.f : 0.5f);
			clouds[0].border_mm.push_back(float(std::min(15 - std::fabs(az), 15 - std::fabs(el)) * deg * R));
		}
	auto fuse = [&](int median_radius, int *ret_off, int *ret_low, int *ret_high, SurfaceStats *ret_stats) {
		SurfaceParams params;
		params.median_radius = median_radius;
		Mesh mesh;
		assert_true(fuse_dense(clouds, {}, cams, params, &mesh, ret_stats).ok());
		*ret_off = *ret_low = *ret_high = 0;
		for (const cv::Point3f &p : mesh.positions) {
			const double az = std::atan2(p.x, p.z) / deg, r = cv::norm(p);
			const double expected = R + (az > 0 ? 3 : 0);
			// Away from the step, where a cell may average both sides.
			if (std::fabs(az) > 0.5)
				*ret_off += std::fabs(r - expected) > 1;
			*ret_low += az < -0.5;
			*ret_high += az > 0.5;
		}
	};
	int off0 = 0, low0 = 0, high0 = 0, off1 = 0, low1 = 0, high1 = 0;
	SurfaceStats s0, s1;
	fuse(0, &off0, &low0, &high0, &s0);
	fuse(3, &off1, &low1, &high1, &s1);
	std::printf("median test: %d spikes, %d vertices off without it, %d with it (%d cells dropped); "
		    "sides %d / %d -> %d / %d vertices\n",
		    spikes, off0, off1, s1.outliers, low0, high0, low1, high1);
	assert_true(spikes >= 10);
	assert_true(2 * off0 >= spikes); // without the test, most spikes leave a vertex off the surface
	assert_int_equal(off1, 0);
	assert_true(s1.outliers >= spikes && s1.outliers < 12 * spikes);
	// The step's two sides stay (all but about a cell column at the step and the spikes' cells).
	assert_true(low1 > 0.97 * low0 && high1 > 0.97 * high0);
}

// A plane slanted 40 degrees against the view rays, with a dome 5 mm in radius on it (a nose tip's
// curvature), a point every 0.3 mm scattered 0.3 mm along its ray. The plane fit takes much of
// the scatter; on the same surface without scatter it leaves the slanted plane where it is, its
// outline included (a one-sided window), and rounds the dome by less than 0.2 mm (the fit's
// price on the tightest curves: a plane through a 2 mm window of a 5 mm sphere).
void fusion_plane_fit_takes_noise_keeps_slopes(void **)
{
	const std::vector<CameraModel> cams = synth::ring();
	const double deg = CV_PI / 180, tilt = 40 * deg;
	const cv::Vec3d m(std::sin(tilt), 0, std::cos(tilt)); // the plane: p . m = 90
	const cv::Vec3d dome = 90 * cv::Vec3d(0, 0, 1) / m[2] + cv::Vec3d(0, -8, 0) - 2.0 * m; // its centre, under the plane
	const double dome_r = 5;
	// Distance along the unit ray n to the surface: the dome's outer side where the ray meets it
	// above the plane, else the plane.
	auto along = [&](const cv::Vec3d &n) {
		double t = 90 / n.dot(m);
		const double b = n.dot(dome), disc = b * b - (dome.dot(dome) - dome_r * dome_r);
		if (disc > 0 && (b + std::sqrt(disc)) * n.dot(m) > 90)
			t = std::max(t, b + std::sqrt(disc));
		return t;
	};
	auto make = [&](double scatter_mm) {
		std::mt19937 rng(7);
		std::normal_distribution<double> noise(0.0, scatter_mm);
		std::vector<DenseCloud> clouds(1);
		for (double el = -12; el <= 12; el += 0.16)
			for (double az = -12; az <= 12; az += 0.16) {
				const cv::Vec3d n(std::cos(el * deg) * std::sin(az * deg), std::sin(el * deg),
						  std::cos(el * deg) * std::cos(az * deg));
				clouds[0].points.emplace_back(cv::Point3d(n * (along(n) + noise(rng))));
				clouds[0].confidence.push_back(1.f);
				clouds[0].border_mm.push_back(float(std::min(12 - std::fabs(az), 12 - std::fabs(el)) * deg * 90));
			}
		return clouds;
	};
	// Each vertex's distance from the surface: RMS over the plane, the largest on the plane's
	// outline (within 1 mm of the mesh's outermost vertex in x) and on the dome's top.
	struct Errors {
		double rms = 0, outline = 0, dome_top = 0;
		int n = 0;
	};
	auto fuse = [&](const std::vector<DenseCloud> &clouds, double fit_mm) {
		SurfaceParams params;
		params.plane_fit_mm = fit_mm;
		Mesh mesh;
		assert_true(fuse_dense(clouds, {}, cams, params, &mesh, nullptr).ok());
		double xmax = -1e9, sum2 = 0;
		for (const cv::Point3f &p : mesh.positions)
			xmax = std::max(xmax, double(p.x));
		Errors e;
		for (const cv::Point3f &p : mesh.positions) {
			const cv::Vec3d v(p.x, p.y, p.z), off = v - dome;
			const double across = cv::norm(off - off.dot(m) * m);
			if (across < 2 && off.dot(m) > 0) {
				e.dome_top = std::max(e.dome_top, std::fabs(cv::norm(off) - dome_r));
				continue;
			}
			if (across < 6)
				continue; // the crease where the dome meets the plane: not a plane, not a dome
			const double err = v.dot(m) - 90;
			sum2 += err * err;
			e.n++;
			if (p.x > xmax - 1)
				e.outline = std::max(e.outline, std::fabs(err));
		}
		e.rms = std::sqrt(sum2 / std::max(1, e.n));
		return e;
	};
	const std::vector<DenseCloud> noisy = make(0.3), clean = make(0);
	const Errors noisy0 = fuse(noisy, 0), noisy1 = fuse(noisy, 1.0);
	const Errors clean0 = fuse(clean, 0), clean1 = fuse(clean, 1.0);
	std::printf("plane fit: scatter RMS %.3f -> %.3f mm; without scatter: plane RMS %.4f -> %.4f, "
		    "outline %.4f -> %.4f, dome top %.3f -> %.3f mm (%d vertices)\n",
		    noisy0.rms, noisy1.rms, clean0.rms, clean1.rms, clean0.outline, clean1.outline, clean0.dome_top,
		    clean1.dome_top, clean1.n);
	assert_true(noisy0.rms > 0.03);
	assert_true(noisy1.rms < 0.6 * noisy0.rms);
	assert_true(clean1.rms < 0.02 && clean1.outline < 0.02);
	assert_true(clean1.dome_top < 0.2);
}

} // namespace

// Flat squares: their interiors (no texture) carry a wrong disparity, as SGBM's smoothness leaves
// it; the textured edges around them are right. The refill gives each interior the quadratic its
// ring agrees on; a square whose ring straddles a step (two surfaces) keeps its values.
static void flat_squares_refilled_from_their_edges(void **)
{
	const cv::Size size(240, 200);
	auto truth = [](int x, int y) { return 40.0 + 0.05 * x - 0.03 * y + 2e-4 * (x - 120) * (x - 120) + 1e-4 * x * y; };
	cv::Mat valid(size, CV_8U, cv::Scalar(255)), std_l(size, CV_32F, cv::Scalar(12)), total(size, CV_32F);
	for (int y = 0; y < size.height; ++y)
		for (int x = 0; x < size.width; ++x)
			total.at<float>(y, x) = float(truth(x, y));
	// 24-px cells: a 16-px flat interior inside an 8-px textured band; interiors off by a tilt.
	int squares = 0;
	for (int y = 0; y < size.height; ++y)
		for (int x = 0; x < size.width; ++x)
			if (x % 24 >= 4 && x % 24 < 20 && y % 24 >= 4 && y % 24 < 20) {
				std_l.at<float>(y, x) = 1;
				total.at<float>(y, x) += float(1.5 + 0.05 * (x % 24));
				squares += x % 24 == 4 && y % 24 == 4;
			}
	// A few mismatched edge pixels (the robust fit must shrug them off)...
	for (int k = 0; k < 40; ++k)
		total.at<float>(2 + 24 * (k % 8), 3 + 24 * (k / 8)) += 6.f;
	// ...and one square (cell (5, 4)) whose ring straddles a step of 8 px: no single quadratic.
	// (4 px before 2026-12-07, with a fit to 0.5 px: at 1 px a ramp fits a 4 px step's ring.)
	const cv::Rect stepped(5 * 24, 4 * 24, 24, 24);
	for (int y = stepped.y; y < stepped.y + 24; ++y)
		for (int x = stepped.x + 12; x < stepped.x + 24; ++x)
			total.at<float>(y, x) += 8.f;
	const cv::Mat before = total.clone();
	// Lit squares: brighter than the edges around them.
	cv::Mat grey(size, CV_8U, cv::Scalar(120));
	grey.setTo(200, std_l <= 4);
	DenseParams params;
	DenseStats stats;
	cv::Mat valid_out = valid.clone();
	const int filled = fill_flat_regions(grey, std_l, params, &valid_out, &total, &stats);
	std::printf("flat refill: %d squares, %d px refilled, %d kept\n", squares, filled, stats.flat_kept);
	assert_int_equal(filled, stats.flat_filled);
	assert_int_equal(stats.flat_kept, 16 * 16);
	assert_int_equal(filled + stats.flat_kept, cv::countNonZero(std_l <= 4));
	assert_int_equal(stats.flat_dropped, 0);
	assert_int_equal(cv::countNonZero(valid_out != valid), 0); // lit squares are never dropped
	double worst = 0;
	for (int y = 0; y < size.height; ++y)
		for (int x = 0; x < size.width; ++x) {
			if (std_l.at<float>(y, x) > 4)
				assert_true(total.at<float>(y, x) == before.at<float>(y, x)); // edges untouched
			else if (stepped.contains(cv::Point(x, y)))
				assert_true(total.at<float>(y, x) == before.at<float>(y, x));
			else
				worst = std::max(worst, std::fabs(total.at<float>(y, x) - truth(x, y)));
		}
	std::printf("flat refill: worst interior off the truth %.4f px (was 1.5-2.3)\n", worst);
	assert_true(worst < 0.01);
	// Switched off, or with no flat pixel, nothing changes.
	cv::Mat untouched = before.clone();
	DenseStats none;
	cv::Mat valid_none = valid.clone();
	assert_int_equal(fill_flat_regions(grey, cv::Mat(size, CV_32F, cv::Scalar(12)), params, &valid_none, &untouched, &none), 0);
	assert_true(cv::countNonZero(untouched != before) == 0);
	assert_int_equal(cv::countNonZero(valid_none != valid), 0);
}

// A flat region whose ring is one-sided (a square cut by the edge of the match: here its ring lies
// along its left and top sides only) leaves the quadratic free on the open side: fitted exactly to
// the ring, it runs 12 px past the ring's range in the far corner. It is not used; without the
// range check it would be. A lit region is not cut into tiles (flat_tile_px): with tiles on, it
// is still not refilled.
static void flat_fit_stays_within_its_ring(void **)
{
	const cv::Size size(120, 100);
	const cv::Rect flat(30, 20, 60, 60);
	auto bowl = [&](int x, int y) { return 30.0 + 0.004 * (x - 30) * (x - 30) + 0.004 * (y - 20) * (y - 20); };
	cv::Mat valid(size, CV_8U, cv::Scalar(255)), std_l(size, CV_32F, cv::Scalar(12)), total(size, CV_32F);
	for (int y = 0; y < size.height; ++y)
		for (int x = 0; x < size.width; ++x)
			total.at<float>(y, x) = float(bowl(x, y));
	std_l(flat).setTo(1);
	total(flat).setTo(40); // SGBM's guess inside
	valid(cv::Rect(flat.br().x, 0, size.width - flat.br().x, size.height)).setTo(0); // open on the right
	valid(cv::Rect(0, flat.br().y, size.width, size.height - flat.br().y)).setTo(0);  // and below
	cv::Mat grey(size, CV_8U, cv::Scalar(120));
	grey(flat).setTo(200); // lit: a square, not a gap
	const cv::Mat before = total.clone();
	DenseParams params;
	params.flat_unfitted_reach_px = 0; // keep SGBM's guess: only the refill is judged here
	cv::Mat v = valid.clone(), t = total.clone();
	DenseStats stats;
	assert_int_equal(fill_flat_regions(grey, std_l, params, &v, &t, &stats), 0);
	assert_int_equal(stats.flat_kept, flat.area());
	assert_int_equal(cv::countNonZero(t != before), 0);
	// Unchecked, the quadratic fills it and overshoots the ring's range.
	DenseParams unchecked = params;
	unchecked.flat_max_overshoot_px = -1;
	cv::Mat v2 = valid.clone(), t2 = total.clone();
	DenseStats st2;
	assert_int_equal(fill_flat_regions(grey, std_l, unchecked, &v2, &t2, &st2), flat.area());
	double ring_max = 0, fill_max = 0;
	for (int y = flat.y - 3; y < flat.br().y; ++y)
		for (int x = flat.x - 3; x < flat.br().x; ++x)
			if (!flat.contains(cv::Point(x, y)) && valid.at<uchar>(y, x))
				ring_max = std::max(ring_max, double(total.at<float>(y, x)));
	for (int y = flat.y; y < flat.br().y; ++y)
		for (int x = flat.x; x < flat.br().x; ++x)
			fill_max = std::max(fill_max, double(t2.at<float>(y, x)));
	std::printf("one-sided ring: ring up to %.1f px, unchecked fill up to %.1f px\n", ring_max, fill_max);
	assert_true(fill_max > ring_max + 10);
}

// One flat region that spans many squares: the dark gaps between lit squares, joined into a
// lattice, over a surface no quadratic follows that far. Fitted whole, its ring (the squares'
// textured edges) fits nothing and it keeps SGBM's guess; cut into `flat_tile_px` tiles, each
// piece fits the edges within its tile and the lattice comes back onto the surface.
static void large_flat_regions_fitted_piecewise(void **)
{
	const cv::Size size(200, 200);
	auto truth = [](int x, int y) { return 40.0 + 4.0 * std::sin(x / 20.0) * std::cos(y / 25.0); };
	// 24 px cells off the tile grid: a gap 8 px wide (4 + 4 across the cell's border), edges of
	// 4 px, a lit square of 8 px.
	enum { kGap, kEdge, kSquare };
	auto part = [](int x, int y) {
		const int cx = (x + 10) % 24, cy = (y + 10) % 24;
		auto of = [](int c) { return c < 4 || c >= 20 ? kGap : c < 8 || c >= 16 ? kEdge : kSquare; };
		return std::min(of(cx), of(cy));
	};
	cv::Mat valid(size, CV_8U, cv::Scalar(255)), std_l(size, CV_32F), total(size, CV_32F);
	cv::Mat grey(size, CV_8U), gap(size, CV_8U, cv::Scalar(0));
	for (int y = 0; y < size.height; ++y)
		for (int x = 0; x < size.width; ++x) {
			const int k = part(x, y);
			std_l.at<float>(y, x) = k == kEdge ? 12.f : 1.f;
			grey.at<uchar>(y, x) = k == kGap ? 40 : k == kEdge ? 120 : 200;
			total.at<float>(y, x) = float(truth(x, y) + (k == kEdge ? 0 : 2)); // SGBM's guess: 2 px off
			gap.at<uchar>(y, x) = k == kGap ? 255 : 0;
		}
	const int gap_px = cv::countNonZero(gap);
	DenseParams params;
	params.flat_unfitted_reach_px = 0; // keep what is not refilled: only the fit is judged
	params.flat_dark_reach_px = 0;
	for (const int tile : {0, 24}) {
		params.flat_tile_px = tile;
		cv::Mat v = valid.clone(), t = total.clone();
		DenseStats stats;
		fill_flat_regions(grey, std_l, params, &v, &t, &stats);
		int refilled = 0;
		double sum2 = 0;
		for (int y = 0; y < size.height; ++y)
			for (int x = 0; x < size.width; ++x)
				if (gap.at<uchar>(y, x)) {
					const double e = t.at<float>(y, x) - truth(x, y);
					sum2 += e * e;
					refilled += t.at<float>(y, x) != total.at<float>(y, x);
				}
		const double rms = std::sqrt(sum2 / gap_px);
		std::printf("gap lattice, tiles of %d px: %d of %d px refilled, RMS %.3f px off the surface\n", tile,
			    refilled, gap_px, rms);
		assert_int_equal(cv::countNonZero(v), size.area());
		if (tile == 0) {
			assert_int_equal(refilled, 0);
			assert_true(rms > 1.9);
		} else {
			assert_true(refilled > 0.9 * gap_px);
			assert_true(rms < 0.2);
		}
	}
}

// A wide flat region darker than its edges (a shadow, the band between two projectors' zones) is
// not a lit square: SGBM's guess holds only near the texture, so its pixels farther than
// `flat_dark_reach_px` from a textured match go; the same region lit (a big square) stays whole.
// Pixels of a flat band kept or dropped against the rule "kept exactly within `reach` pixels of
// the band's edge" (a pixel one off the boundary either way is not judged: the distance
// transform's metric rounds there).
static int misjudged_in_band(const cv::Mat &valid, cv::Rect band, double reach)
{
	int wrong = 0;
	for (int y = band.y; y < band.y + band.height; ++y)
		for (int x = band.x; x < band.x + band.width; ++x) {
			const int d = std::min({x - band.x + 1, band.x + band.width - x, y - band.y + 1,
						band.y + band.height - y});
			const bool kept = valid.at<uchar>(y, x) != 0;
			wrong += (d <= reach) != kept && std::abs(d - reach) > 1;
		}
	return wrong;
}

static void dark_flat_regions_dropped_beyond_reach(void **)
{
	const cv::Size size(160, 120);
	const cv::Rect band(40, 20, 60, 80); // 60 x 80 px without texture
	cv::Mat valid(size, CV_8U, cv::Scalar(255)), std_l(size, CV_32F, cv::Scalar(12));
	cv::Mat total(size, CV_32F, cv::Scalar(30));
	std_l(band).setTo(1);
	DenseParams params;
	for (const int lit : {0, 1}) {
		cv::Mat grey(size, CV_8U, cv::Scalar(120)), v = valid.clone(), t = total.clone();
		grey(band).setTo(lit ? 220 : 25);
		DenseStats stats;
		fill_flat_regions(grey, std_l, params, &v, &t, &stats);
		std::printf("flat %s region: %d px dropped of %d\n", lit ? "lit" : "dark", stats.flat_dropped, band.area());
		if (lit) {
			assert_int_equal(stats.flat_dropped, 0);
			assert_int_equal(cv::countNonZero(v), size.area());
			continue;
		}
		// Inside the band, a pixel stays exactly when it is within reach of the band's edge.
		assert_int_equal(misjudged_in_band(v, band, params.flat_dark_reach_px), 0);
		assert_true(stats.flat_dropped > (band.width - 12) * (band.height - 12));
		assert_int_equal(cv::countNonZero(v), size.area() - stats.flat_dropped);
		// Switched off: kept.
		DenseParams off = params;
		off.flat_dark_reach_px = 0;
		cv::Mat v2 = valid.clone(), t2 = total.clone();
		DenseStats s2;
		fill_flat_regions(grey, std_l, off, &v2, &t2, &s2);
		assert_int_equal(s2.flat_dropped, 0);
		assert_int_equal(cv::countNonZero(v2), size.area());
	}
}

// A bright flat region whose ring fits no quadratic (here: its ring straddles a 4 px step, so
// 50 % of it agrees with any one fit) keeps SGBM's values only within `flat_unfitted_reach_px` of
// a textured match; a lit square of the usual size (16 px: no pixel beyond 8 px of its edge)
// loses nothing, and a fitted region of any size loses nothing.
static void unfitted_flat_regions_dropped_beyond_reach(void **)
{
	const cv::Size size(160, 120);
	const cv::Rect band(40, 20, 60, 80); // 60 x 80 px without texture
	cv::Mat valid(size, CV_8U, cv::Scalar(255)), std_l(size, CV_32F, cv::Scalar(12));
	cv::Mat total(size, CV_32F, cv::Scalar(30));
	total(cv::Rect(70, 0, 90, 120)).setTo(38); // a step through the band: no quadratic fits its ring
	std_l(band).setTo(1);
	cv::Mat grey(size, CV_8U, cv::Scalar(120));
	grey(band).setTo(220); // lit: not the dark rule
	DenseParams params;
	cv::Mat v = valid.clone(), t = total.clone();
	DenseStats stats;
	assert_int_equal(fill_flat_regions(grey, std_l, params, &v, &t, &stats), 0);
	std::printf("unfitted flat region: %d px dropped of %d, %d kept\n", stats.flat_unfitted_dropped, band.area(),
		    stats.flat_kept);
	assert_int_equal(stats.flat_dropped, 0);
	assert_int_equal(misjudged_in_band(v, band, params.flat_unfitted_reach_px), 0);
	assert_true(stats.flat_unfitted_dropped > (band.width - 20) * (band.height - 20));
	assert_int_equal(stats.flat_unfitted_dropped + stats.flat_kept, band.area());
	assert_int_equal(cv::countNonZero(v), size.area() - stats.flat_unfitted_dropped);
	assert_true(cv::countNonZero(t != total) == 0); // what stays keeps its value
	// A 16 px square with the same step: kept whole.
	{
		cv::Mat s16(size, CV_32F, cv::Scalar(12)), v16 = valid.clone(), t16 = total.clone();
		s16(cv::Rect(62, 40, 16, 16)).setTo(1);
		DenseStats st;
		fill_flat_regions(grey, s16, params, &v16, &t16, &st);
		assert_int_equal(st.flat_kept, 16 * 16);
		assert_int_equal(st.flat_unfitted_dropped, 0);
		assert_int_equal(cv::countNonZero(v16), size.area());
	}
	// No step: the ring fits, the band is refilled, nothing dropped.
	{
		cv::Mat v2 = valid.clone(), t2(size, CV_32F, cv::Scalar(30));
		DenseStats st;
		assert_int_equal(fill_flat_regions(grey, std_l, params, &v2, &t2, &st), band.area());
		assert_int_equal(st.flat_unfitted_dropped, 0);
		assert_int_equal(cv::countNonZero(v2), size.area());
	}
	// Switched off: kept.
	DenseParams off = params;
	off.flat_unfitted_reach_px = 0;
	cv::Mat v3 = valid.clone(), t3 = total.clone();
	DenseStats s3;
	fill_flat_regions(grey, std_l, off, &v3, &t3, &s3);
	assert_int_equal(s3.flat_unfitted_dropped, 0);
	assert_int_equal(s3.flat_kept, band.area());
	assert_int_equal(cv::countNonZero(v3), size.area());
}

// The refinement upsamples the disparity to the cameras' resolution; a pixel next to a hole
// (unmatched: carried as 0) must keep its own disparity, not a blend with the hole's 0. Blank
// frames give no gradient, so Lucas-Kanade moves nothing and every valid pixel must come back
// exactly as it went in (a quarter of it lost next to a hole cut every dark gap's squares apart).
// A dim booth: the gaps between the squares are too dark to match, so the matches are a lattice
// of squares. The gaps get the surface's disparity back (a quadratic over the squares around
// them); a dark gap across a step (a shadow between two surfaces) and a dark area wider than a
// gap stay empty.
static void dark_gaps_bridged_between_squares(void **)
{
	const cv::Size size(240, 180);
	const double pitch = 30;
	// The slide's gaps are 0.3 of the pitch; what falls below `min_intensity` on a dim booth is
	// their core, blurred edges aside.
	const int gap = 6;
	const int step_x = 210 + gap; // the gap column x = 210 .. step_x - 1 lies between two surfaces
	auto truth = [&](double x, double y) { return 20 + 0.05 * x - 0.03 * y + 1e-4 * (x - 120) * (x - 120); };
	cv::Mat total(size, CV_32F), valid(size, CV_8U), dark(size, CV_8U, cv::Scalar(0));
	for (int y = 0; y < size.height; ++y)
		for (int x = 0; x < size.width; ++x) {
			const bool in_gap = x % int(pitch) < gap || y % int(pitch) < gap;
			total.at<float>(y, x) = in_gap ? 0.f : float(truth(x, y));
			valid.at<uchar>(y, x) = in_gap ? 0 : 255;
			dark.at<uchar>(y, x) = in_gap ? 255 : 0;
		}
	// A dark hole two pitches wide in the middle: not a gap.
	const cv::Rect hole(90, 60, 60, 60);
	valid(hole).setTo(0);
	dark(hole).setTo(255);
	// A step of 6 px across the gap column at x = 210: left and right of it are two surfaces.
	for (int y = 0; y < size.height; ++y)
		for (int x = step_x; x < size.width; ++x)
			if (valid.at<uchar>(y, x))
				total.at<float>(y, x) += 6.f;
	const cv::Mat before = valid.clone();
	DenseParams params;
	cv::Mat bridged;
	const int n = bridge_dark_gaps(dark, pitch, params, &valid, &total, &bridged);
	int inner_gaps = 0, inner_bridged = 0, in_hole = 0, at_step = 0;
	double worst = 0;
	for (int y = 0; y < size.height; ++y)
		for (int x = 0; x < size.width; ++x) {
			const bool gap_px = !before.at<uchar>(y, x);
			const bool b = bridged.at<uchar>(y, x) != 0;
			assert_true(!b || gap_px);			  // matches are never touched
			assert_true(b == (valid.at<uchar>(y, x) != 0 && gap_px)); // bridged = set in valid
			const cv::Rect near_hole(hole.x - int(pitch), hole.y - int(pitch), hole.width + 2 * int(pitch),
						 hole.height + 2 * int(pitch));
			if (hole.contains(cv::Point(x, y))) {
				// Only a gap's width into the hole from its edge can the closing reach.
				const int d = std::min({x - hole.x, hole.x + hole.width - 1 - x, y - hole.y,
							hole.y + hole.height - 1 - y});
				in_hole += b && d > gap;
				continue;
			}
			if (x >= 210 && x < step_x) {
				at_step += b;
				continue;
			}
			// Gaps wholly inside the lattice (not at the image's border, which the closing
			// does not reach beyond, nor beside the hole, where a side is missing).
			if (gap_px && x >= int(pitch) && y >= int(pitch) && x < 200 && y < 150 &&
			    !near_hole.contains(cv::Point(x, y))) {
				inner_gaps++;
				inner_bridged += b;
				if (b)
					worst = std::max(worst, std::fabs(total.at<float>(y, x) - truth(x, y)));
			}
		}
	std::printf("dark gaps: %d bridged, inner gaps %d of %d, worst %.4f px; in the hole %d, at the step %d\n", n,
		    inner_bridged, inner_gaps, worst, in_hole, at_step);
	assert_int_equal(n, cv::countNonZero(bridged));
	// Missed: the gap's last column before a square, where the far side is at the window's edge.
	assert_true(inner_bridged >= 0.85 * inner_gaps);
	assert_true(worst < 0.05);
	assert_int_equal(in_hole, 0);
	assert_int_equal(at_step, 0);
	// Off: nothing changes.
	params.dark_bridge_pitches = 0;
	cv::Mat v = before.clone(), t = total.clone();
	assert_int_equal(bridge_dark_gaps(dark, pitch, params, &v, &t, &bridged), 0);
	assert_int_equal(cv::countNonZero(v != before), 0);
}

static void refinement_keeps_disparity_next_to_holes(void **)
{
	const std::vector<CameraModel> cams = synth::ring();
	RectifiedPair rp;
	assert_true(rectify_pair(cams[0], cams[1], 0.5, &rp).ok());
	const cv::Mat fa(cams[0].size, CV_8UC3, cv::Scalar(120, 120, 120)), fb(cams[1].size, CV_8UC3, cv::Scalar(120, 120, 120));
	cv::Mat valid(rp.size, CV_8U, cv::Scalar(0)), disparity(rp.size, CV_32F, cv::Scalar(0));
	const cv::Rect face(rp.size.width / 4, rp.size.height / 4, rp.size.width / 2, rp.size.height / 2);
	valid(face).setTo(255);
	// Dark gaps between squares: 2-px unmatched lines every 12 px, as on a dim booth.
	for (int y = face.y; y < face.br().y; ++y)
		for (int x = face.x; x < face.br().x; ++x)
			if ((x - face.x) % 12 < 2 || (y - face.y) % 12 < 2)
				valid.at<uchar>(y, x) = 0;
	for (int y = 0; y < rp.size.height; ++y)
		for (int x = 0; x < rp.size.width; ++x)
			disparity.at<float>(y, x) = valid.at<uchar>(y, x) ? float(60 + 0.02 * x) : 0.f;
	const cv::Mat before = disparity.clone();
	const DenseParams params;
	const cv::Rect frame(cv::Point(0, 0), rp.size);
	refine_subpixel(refine_views(fa, fb, cams[0], cams[1], rp, params.refine_scale, frame), valid, params, &disparity);
	// Lucas-Kanade moves a pixel by at most 3 x 0.5 px at the cameras' resolution (0.75 here), and
	// only where the rectified frames' own borders give it a gradient; no pixel next to a hole
	// may move more (the blend with the hole's 0 moved each by ~15 px).
	double worst = 0;
	int moved = 0, next_to_hole_moved = 0;
	for (int y = 1; y < rp.size.height - 1; ++y)
		for (int x = 1; x < rp.size.width - 1; ++x) {
			if (!valid.at<uchar>(y, x))
				continue;
			const double change = std::fabs(disparity.at<float>(y, x) - before.at<float>(y, x));
			worst = std::max(worst, change);
			moved += change > 1e-3;
			next_to_hole_moved += change > 1.0 && (!valid.at<uchar>(y - 1, x) || !valid.at<uchar>(y, x - 1));
		}
	std::printf("refinement next to holes: worst change %.4f px, %d px moved, %d next to a hole (was ~15 px "
		    "there: a quarter of the disparity)\n", worst, moved, next_to_hole_moved);
	assert_true(worst <= 0.75 + 1e-3);
	assert_int_equal(next_to_hole_moved, 0);
}

// The sphere's true disparity in pair 1-2 rectified at the render's own resolution: each
// rectified left pixel's ray (from the camera's centre through its point at 500 mm) meets the
// sphere; that point in the rectified right view. `valid` where both cameras see it.
static void sphere_disparity(const SphereScene &s, RectifiedPair *ret_rp, cv::Mat *ret_truth, cv::Mat *ret_valid)
{
	const CameraModel &a = s.cams[1], &b = s.cams[2];
	RectifiedPair &rp = *ret_rp;
	assert_true(rectify_pair(a, b, 1.0, &rp).ok());
	const double d500 = rp.f * rp.baseline / 500 + (rp.cx1 - rp.cx2);
	cv::Mat truth(rp.size, CV_32F, cv::Scalar(0)), valid(rp.size, CV_8U, cv::Scalar(0));
	for (int y = 0; y < rp.size.height; ++y)
		for (int x = 0; x < rp.size.width; ++x) {
			const cv::Vec3d p0(a.centre()), p1(rectified_to_world(rp, a, x, y, d500));
			cv::Vec3d dir = p1 - p0;
			dir *= 1.0 / cv::norm(dir);
			const cv::Vec3d o = p0 - s.centre;
			const double bq = o.dot(dir), cq = o.dot(o) - s.radius * s.radius, disc = bq * bq - cq;
			if (disc <= 0)
				continue;
			const double t = -bq - std::sqrt(disc); // the near side
			const cv::Vec3d w = p0 + dir * t, n = (w - s.centre) * (1.0 / s.radius);
			if (!synth::sees(a, cv::Point3d(w), n) || !synth::sees(b, cv::Point3d(w), n))
				continue;
			const cv::Point2d rb = rectify_points(rp, b, 1, project_points(b, {cv::Point3d(w)}))[0];
			truth.at<float>(y, x) = float(x - rb.x);
			valid.at<uchar>(y, x) = 255;
		}
	*ret_truth = truth;
	*ret_valid = valid;
}

// The refinement works at the cameras' resolution, where full-resolution x is twice matching x
// (the rectification's geometry doubled). Started from the sphere's true disparity it must stay
// there whatever the disparity's slope: upsampled with pixel centres aligned instead
// (cv::resize's convention, before 2026-12-06) each pixel began a quarter of a matching pixel
// away and was refined to the truth there, which moved every matching pixel by about a quarter
// of the slope (measured: the change regressed on the slope with coefficient 0.175; now 0.033).
static void refinement_starts_where_the_disparity_is(void **)
{
	SphereScene s;
	render_sphere(&s);
	const CameraModel &a = s.cams[1], &b = s.cams[2];
	RectifiedPair rp;
	cv::Mat truth, valid;
	sphere_disparity(s, &rp, &truth, &valid);
	// Away from the sphere's outline, where the slope is steep.
	cv::erode(valid, valid, cv::Mat(), cv::Point(-1, -1), 12);
	assert_true(cv::countNonZero(valid) > 20000);
	cv::Mat disparity = truth.clone();
	const DenseParams params;
	const cv::Rect frame(cv::Point(0, 0), rp.size);
	refine_subpixel(refine_views(s.frames[1], s.frames[2], a, b, rp, params.refine_scale, frame), valid, params,
			&disparity);
	// The change against the slope along the rows, over the pixels the refinement moved.
	std::vector<double> change;
	double sum_gg = 0, sum_ge = 0;
	for (int y = 0; y < rp.size.height; ++y)
		for (int x = 1; x < rp.size.width - 1; ++x) {
			if (!valid.at<uchar>(y, x) || disparity.at<float>(y, x) == truth.at<float>(y, x))
				continue;
			const double e = disparity.at<float>(y, x) - truth.at<float>(y, x);
			const double g = (truth.at<float>(y, x + 1) - truth.at<float>(y, x - 1)) / 2;
			change.push_back(std::fabs(e));
			sum_gg += g * g;
			sum_ge += g * e;
		}
	assert_true(change.size() > 5000); // the pattern's texture refines most pixels
	std::sort(change.begin(), change.end());
	const double median = change[change.size() / 2], per_slope = sum_ge / sum_gg;
	std::printf("refinement from the true disparity: %zu px moved, median %.4f px, change per unit of slope "
		    "%.4f (a quarter-pixel start: ~0.25)\n",
		    change.size(), median, per_slope);
	assert_true(std::fabs(per_slope) < 0.08);
	// What Lucas-Kanade's windows leave on this half-resolution render (measured 0.149 px).
	assert_true(median < 0.2);
}

// The refinement reads the right view wherever a match lands: its left view covers the matched
// pixels' box, but a match's right window can lie beyond that box by the disparity. Before
// 2026-12-07 the right view was cut to the same box, and the matches landing beyond it read black:
// they kept SGBM's value or took a wrong step (one pair of bench booth 103-scan1039: 43 % of its
// refined pixels). Refined on views over the box, they must come out as on views over the frame.
static void refinement_reads_the_right_view_beyond_the_left_box(void **)
{
	SphereScene s;
	render_sphere(&s);
	RectifiedPair rp;
	cv::Mat truth, valid;
	sphere_disparity(s, &rp, &truth, &valid);
	cv::erode(valid, valid, cv::Mat(), cv::Point(-1, -1), 12);
	const cv::Rect box = cv::boundingRect(valid), frame(cv::Point(0, 0), rp.size);
	const DenseParams params;
	cv::Mat on_box = truth + 0.3f, on_frame = on_box.clone();
	const cv::Mat &fa = s.frames[1], &fb = s.frames[2];
	const CameraModel &a = s.cams[1], &b = s.cams[2];
	refine_subpixel(refine_views(fa, fb, a, b, rp, params.refine_scale, box), valid, params, &on_box);
	refine_subpixel(refine_views(fa, fb, a, b, rp, params.refine_scale, frame), valid, params, &on_frame);
	// Beyond: the match's window (6 camera pixels either side, 3 matching) leaves the box.
	int beyond = 0, beyond_moved = 0, differ = 0;
	double worst = 0;
	for (int y = 0; y < rp.size.height; ++y)
		for (int x = 0; x < rp.size.width; ++x) {
			if (!valid.at<uchar>(y, x))
				continue;
			const double xr = x - truth.at<float>(y, x);
			const double d = std::fabs(on_box.at<float>(y, x) - on_frame.at<float>(y, x));
			worst = std::max(worst, d);
			differ += d > 1e-3;
			if (xr < box.x + 4 || xr > box.br().x - 5) {
				beyond++;
				beyond_moved += std::fabs(on_box.at<float>(y, x) - truth.at<float>(y, x) - 0.3f) > 1e-3;
			}
		}
	std::printf("refinement beyond the left box: %d px, %d of them refined; against views over the frame %d px "
		    "differ, worst %.5f px\n", beyond, beyond_moved, differ, worst);
	assert_true(beyond > 2000);
	assert_true(beyond_moved > beyond / 2);
	assert_int_equal(differ, 0);
}

// Ramps of known slope: falling along the rows is a surface stretched in the second view (kept
// down to max_falling_gradient), rising or changing down the columns beyond
// max_disparity_gradient is edge-on (dropped).
static void steep_test_keeps_stretched_surfaces(void **)
{
	const DenseParams params; // 1.5 rising / down the columns, 3 falling
	const cv::Size size(60, 20);
	const cv::Mat valid(size, CV_8U, cv::Scalar(255));
	auto steep_share = [&](double along, double down) {
		cv::Mat d(size, CV_32F);
		for (int y = 0; y < size.height; ++y)
			for (int x = 0; x < size.width; ++x)
				d.at<float>(y, x) = float(100 + along * x + down * y);
		const cv::Mat bad = steep_pixels(valid, d, params);
		return double(cv::countNonZero(bad)) / double((size.width - 2) * (size.height - 2));
	};
	std::printf("steep share: falling 2 -> %.2f, falling 4 -> %.2f, rising 2 -> %.2f, rising 1 -> %.2f, "
		    "down 2 -> %.2f, down -2 -> %.2f\n", steep_share(-2, 0), steep_share(-4, 0), steep_share(2, 0),
		    steep_share(1, 0), steep_share(0, 2), steep_share(0, -2));
	assert_true(steep_share(-2, 0) == 0.0);
	assert_true(steep_share(-2.9, 0) == 0.0);
	assert_true(steep_share(-4, 0) == 1.0);
	assert_true(steep_share(2, 0) == 1.0);
	assert_true(steep_share(1, 0) == 0.0);
	assert_true(steep_share(0, 2) == 1.0);
	assert_true(steep_share(0, -2) == 1.0);
	// Only pixels whose neighbours are matched are judged: a lone valid pixel is never steep.
	cv::Mat lone(size, CV_8U, cv::Scalar(0));
	lone.at<uchar>(10, 30) = 255;
	cv::Mat d(size, CV_32F, cv::Scalar(0));
	d.at<float>(10, 30) = 50;
	assert_int_equal(cv::countNonZero(steep_pixels(lone, d, params)), 0);
}

// A sphere cap (one pair's) and, 3 degrees beyond its edge (a gap of ~4.7 mm, far wider than a
// triangle's longest allowed edge), a patch 2 x 2 degrees: far under 2 % of the cap, so a
// piece the size rule would drop. Seen by one pair only, it goes (a lone sheet is more often a
// mismatch than not); seen by two pairs that agree on it, it stays; seen by one pair with two of
// the code's points on it, it stays too — with one, or with two 3 mm off it, it goes.
void fusion_keeps_small_pieces_two_pairs_or_the_code_vouch_for(void **)
{
	const std::vector<CameraModel> cams = synth::ring();
	const double R = 90, deg = CV_PI / 180;
	// The point at azimuth `az` and elevation `el` (degrees) on the sphere of radius r.
	auto on_sphere = [&](double az, double el, double r) {
		return cv::Point3f(cv::Point3d(r * std::cos(el * deg) * std::sin(az * deg), r * std::sin(el * deg),
					       r * std::cos(el * deg) * std::cos(az * deg)));
	};
	auto add = [&](DenseCloud *cloud, double az0, double az1, double el0, double el1, double r) {
		for (double el = el0; el <= el1 + 1e-9; el += 0.1)
			for (double az = az0; az <= az1 + 1e-9; az += 0.1) {
				cloud->points.push_back(on_sphere(az, el, r));
				cloud->confidence.push_back(1.f);
				cloud->border_mm.push_back(
					float(std::min({az - az0, az1 - az, el - el0, el1 - el}) * deg * R));
			}
	};
	// Vertices of the mesh on the patch (azimuth beyond the cap's edge).
	auto patch_vertices = [&](const std::vector<DenseCloud> &clouds, const std::vector<cv::Point3f> &code,
				  SurfaceStats *ret_stats) {
		Mesh mesh;
		assert_true(fuse_dense(clouds, code, cams, SurfaceParams(), &mesh, ret_stats).ok());
		int on_patch = 0;
		for (const cv::Point3f &p : mesh.positions)
			on_patch += std::atan2(p.x, p.z) / deg > 21;
		return on_patch;
	};
	std::vector<DenseCloud> one(2), two(3);
	add(&one[0], -20, 20, -20, 20, R);
	add(&one[1], 23, 25, -1, 1, R);
	two[0] = one[0];
	add(&two[1], 23, 25, -1, 1, R + 0.1);
	add(&two[2], 23, 25, -1, 1, R - 0.1);
	SurfaceStats s_one, s_two;
	const int one_pair = patch_vertices(one, {}, &s_one), two_pairs = patch_vertices(two, {}, &s_two);
	std::printf("small piece: %d vertices kept seen by one pair (%d triangles dropped), %d seen by two\n",
		    one_pair, s_one.piece_triangles_dropped, two_pairs);
	assert_int_equal(one_pair, 0);
	assert_true(s_one.piece_triangles_dropped > 0);
	assert_int_equal(s_one.piece_triangles_two_pairs, 0);
	assert_true(s_two.piece_triangles_two_pairs > 0);
	// The patch's cells, less its trimmed outline: ~ (2 degrees / 0.22-degree cells)^2.
	assert_true(two_pairs > 40);
	assert_int_equal(s_two.piece_triangles_dropped, 0);
	assert_int_equal(s_two.piece_triangles_code, 0);

	// The code's points at azimuth 24 and elevations -0.5 / +0.5 (inside the patch), radius r.
	auto code_at = [&](double r, int count) {
		std::vector<cv::Point3f> code;
		for (int i = 0; i < count; ++i)
			code.push_back(on_sphere(24, i - 0.5, r));
		code.push_back(on_sphere(0, 0, R)); // one on the cap, which vouches for nothing
		return code;
	};
	SurfaceStats s_code, s_code_one, s_code_off;
	const int vouched = patch_vertices(one, code_at(R, 2), &s_code);
	const int one_point = patch_vertices(one, code_at(R, 1), &s_code_one);
	const int off = patch_vertices(one, code_at(R + 3, 2), &s_code_off);
	std::printf("small piece, one pair: %d vertices kept with two code points on it, %d with one, %d with two "
		    "3 mm off\n",
		    vouched, one_point, off);
	assert_true(vouched > 40);
	assert_true(s_code.piece_triangles_code > 0);
	assert_int_equal(s_code.piece_triangles_dropped, 0);
	assert_int_equal(one_point, 0);
	assert_int_equal(s_code_one.piece_triangles_code, 0);
	assert_int_equal(off, 0);
	assert_int_equal(s_code_off.piece_triangles_code, 0);
	assert_true(s_code_off.piece_triangles_dropped > 0);
	// The code's points change nothing else: the cap is the same with and without them.
	assert_int_equal(s_code.vertices - vouched, s_one.vertices - one_pair);

	// A long piece (elevation -1 to 11 degrees, ~19 mm) with the code's points at its lower end
	// only: what lies within piece_code_reach_mm (5 mm, ~3.2 degrees) of them stays, the rest goes.
	std::vector<DenseCloud> long_piece(2);
	long_piece[0] = one[0];
	add(&long_piece[1], 23, 25, -1, 11, R);
	Mesh mesh;
	SurfaceStats s_long;
	assert_true(fuse_dense(long_piece, code_at(R, 2), cams, SurfaceParams(), &mesh, &s_long).ok());
	double top = -90;
	int kept = 0;
	for (const cv::Point3f &p : mesh.positions)
		if (std::atan2(p.x, p.z) / deg > 21) {
			kept++;
			top = std::max(top, std::asin(p.y / cv::norm(p)) / deg);
		}
	std::printf("long piece: %d vertices kept, up to elevation %.1f degrees\n", kept, top);
	assert_true(kept > 40);
	assert_true(top > 2.5 && top < 4.5);
	assert_true(s_long.piece_triangles_dropped > 0);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(rectification_reprojects_exactly),
		cmocka_unit_test(rectification_keeps_diagonal_baselines_on_x),
		cmocka_unit_test(prior_is_linear_in_its_triangles),
		cmocka_unit_test(dense_points_lie_on_the_sphere),
		cmocka_unit_test(coarse_search_works_without_code),
		cmocka_unit_test(coarse_search_spans_the_volume_when_seeds_cluster),
		cmocka_unit_test(guide_points_give_the_prior),
		cmocka_unit_test(prepared_pair_matches_again_unchanged),
		cmocka_unit_test(matches_beside_refused_pixels_dropped),
		cmocka_unit_test(dense_refuses_bad_input),
		cmocka_unit_test(flat_squares_refilled_from_their_edges),
		cmocka_unit_test(dark_flat_regions_dropped_beyond_reach),
		cmocka_unit_test(unfitted_flat_regions_dropped_beyond_reach),
		cmocka_unit_test(flat_fit_stays_within_its_ring),
		cmocka_unit_test(large_flat_regions_fitted_piecewise),
		cmocka_unit_test(dark_gaps_bridged_between_squares),
		cmocka_unit_test(refinement_keeps_disparity_next_to_holes),
		cmocka_unit_test(refinement_starts_where_the_disparity_is),
		cmocka_unit_test(refinement_reads_the_right_view_beyond_the_left_box),
		cmocka_unit_test(steep_test_keeps_stretched_surfaces),
		cmocka_unit_test(fusion_makes_one_sheet),
		cmocka_unit_test(fusion_trims_the_outline_not_the_holes),
		cmocka_unit_test(fusion_drops_spikes_keeps_steps),
		cmocka_unit_test(fusion_plane_fit_takes_noise_keeps_slopes),
		cmocka_unit_test(fusion_keeps_small_pieces_two_pairs_or_the_code_vouch_for),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
