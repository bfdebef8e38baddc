// Random booths (tools/sim/booth.cpp): every drawn value inside its documented range, the same
// seed gives the same booth, the written calibration's error is the size asked for, slide
// masks are rendered and are what the evaluation counts as lit, booth.yaml gives the rig back,
// and the widened head family stays inside its ranges.
#include "eval/eval.hpp"
#include "sim/sim.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <setjmp.h>
#include <string>
#include <unistd.h>

extern "C" {
#include <cmocka.h>
}

using namespace facescan;
using namespace facescan::sim;

static bool inside(const Interval &r, double v, double tol = 1e-9)
{
	return v >= r.lo - tol && v <= r.hi + tol;
}

static double slide_pitch()
{
	Pattern p;
	assert_true(default_pattern(SlideSpec(), &p).ok());
	return p.pitch;
}

// Where a projector throws slide pixel coordinates on a point (pinhole).
static cv::Point2d slide_xy(const SimProjector &p, const cv::Vec3d &x)
{
	cv::Vec3d u = p.K * (p.R * x + p.T);
	return cv::Point2d(u[0] / u[2], u[1] / u[2]);
}

static double polygon_test(const std::vector<cv::Point2d> &poly, const cv::Point2d &q)
{
	std::vector<cv::Point2f> c;
	for (const cv::Point2d &p : poly)
		c.emplace_back(float(p.x), float(p.y));
	return cv::pointPolygonTest(c, cv::Point2f(float(q.x), float(q.y)), true);
}

static void test_ranges_honoured(void **)
{
	const BoothRanges &R = booth_ranges();
	const double pitch_px = slide_pitch();
	int masked = 0, quarter[4] = {0, 0, 0, 0};
	double img_pitch_lo = 1e9, img_pitch_hi = 0;
	const int n = 200;
	for (uint64_t seed = 1; seed <= uint64_t(n); seed++) {
		RandomBooth b;
		assert_true(random_booth(seed, pitch_px, &b).ok());
		assert_int_equal(b.rig.cameras.size(), 4);
		assert_int_equal(b.rig.projectors.size(), 3);
		for (int i = 0; i < 4; i++) {
			const SimCamera &c = b.rig.cameras[size_t(i)];
			assert_true(inside(R.cam_azimuth_deg[i], b.cam_azimuth_deg[size_t(i)]));
			assert_true(inside(R.cam_elevation_deg, b.cam_elevation_deg[size_t(i)]));
			assert_true(inside(R.cam_distance_mm, b.cam_distance_mm[size_t(i)]));
			if (i > 0)
				assert_true(inside(R.cam_gap_deg, b.cam_azimuth_deg[size_t(i)] - b.cam_azimuth_deg[size_t(i) - 1]));
			// Left to right: each camera's centre is further towards +x than the previous.
			if (i > 0)
				assert_true(c.model.centre()[0] > b.rig.cameras[size_t(i) - 1].model.centre()[0]);
			assert_true(inside(R.cam_width_px, c.model.size.width, 8));
			assert_true(c.model.size.height >= 1440 / 1.6 - 2 && c.model.size.height <= 1760 / 1.25 + 2);
			// Framing: 240 mm at the camera's distance spans cam_fill of the height.
			const double fill = c.model.K(0, 0) * 240 / b.cam_distance_mm[size_t(i)] / c.model.size.height;
			assert_true(inside(R.cam_fill, fill, 1e-6));
			assert_true(inside(R.cam_k1, c.model.dist[0]) && inside(R.cam_k2, c.model.dist[1]));
			assert_true(inside(R.cam_p, c.model.dist[2]) && inside(R.cam_p, c.model.dist[3]));
			assert_true(inside(R.cam_exposure, c.exposure));
			assert_true(inside(R.calibration_error_px, b.calibration_error_px[size_t(i)]));
			// The nominal head centre is in front of every camera and inside its image.
			cv::Vec3d x = c.model.R * cv::Vec3d(0, -10, 40) + c.model.T;
			assert_true(x[2] > 300);
			cv::Vec3d u = c.model.K * x;
			assert_true(u[0] / u[2] > 0 && u[0] / u[2] < c.model.size.width);
			assert_true(u[1] / u[2] > 0 && u[1] / u[2] < c.model.size.height);
			for (double pmm : b.proj_pitch_mm) {
				double px = pmm * c.model.K(0, 0) / b.cam_distance_mm[size_t(i)];
				img_pitch_lo = std::min(img_pitch_lo, px);
				img_pitch_hi = std::max(img_pitch_hi, px);
			}
		}
		for (int j = 0; j < 3; j++) {
			const SimProjector &p = b.rig.projectors[size_t(j)];
			assert_true(inside(R.proj_azimuth_deg[j], b.proj_azimuth_deg[size_t(j)]));
			assert_true(inside(R.proj_elevation_deg, b.proj_elevation_deg[size_t(j)]));
			assert_true(inside(R.proj_distance_mm, b.proj_distance_mm[size_t(j)]));
			assert_true(inside(R.proj_pitch_mm, b.proj_pitch_mm[size_t(j)]));
			// The pitch is what the focal length gives at the projector's distance.
			assert_true(std::fabs(pitch_px * b.proj_distance_mm[size_t(j)] / p.K(0, 0) - b.proj_pitch_mm[size_t(j)]) < 1e-9);
			const double roll = b.proj_roll_deg[size_t(j)];
			const int q = int(std::lround(roll / 90.0));
			assert_true(q >= 0 && q <= 3);
			assert_true(inside(R.proj_roll_extra_deg, roll - 90.0 * q));
			quarter[q]++;
			assert_true(p.size == cv::Size(1024, 768));
			assert_int_equal(p.mask.empty(), !b.masked);
			for (const cv::Point2d &v : p.mask)
				assert_true(v.x >= -0.5 - 1e-6 && v.y >= -0.5 - 1e-6 && v.x <= 1023.5 + 1e-6 && v.y <= 767.5 + 1e-6);
		}
		if (b.masked) {
			masked++;
			assert_true(inside(R.zone_left_mm, b.zone_left_mm) && inside(R.zone_right_mm, b.zone_right_mm));
			assert_true(inside(R.zone_overlap_mm, b.zone_overlap_mm));
			// Each projector lights its own zone at the face depth and not beyond its edge.
			const double o = b.zone_overlap_mm, zl = b.zone_left_mm, zr = b.zone_right_mm;
			const double inner[3] = {zl - 10, (zl + zr) / 2, zr + 10};
			for (int j = 0; j < 3; j++) {
				const SimProjector &p = b.rig.projectors[size_t(j)];
				cv::Point2d in = slide_xy(p, cv::Vec3d(inner[j], 0, 60));
				bool on_slide = in.x > 0 && in.y > 0 && in.x < 1023 && in.y < 767;
				if (on_slide)
					assert_true(polygon_test(p.mask, in) > 0);
				if (j == 0)
					assert_true(polygon_test(p.mask, slide_xy(p, cv::Vec3d(zl + o + 5, 0, 60))) < 0);
				if (j == 2)
					assert_true(polygon_test(p.mask, slide_xy(p, cv::Vec3d(zr - o - 5, 0, 60))) < 0);
				if (j == 1) {
					assert_true(polygon_test(p.mask, slide_xy(p, cv::Vec3d(zl - o - 5, 0, 60))) < 0);
					assert_true(polygon_test(p.mask, slide_xy(p, cv::Vec3d(zr + o + 5, 0, 60))) < 0);
				}
			}
		}
		for (int k = 0; k < 3; k++)
			assert_true(inside(R.head_offset_mm, b.head_offset_mm[k]));
		assert_true(inside(R.head_yaw_deg, b.head_yaw_deg) && inside(R.head_pitch_deg, b.head_pitch_deg));
		assert_true(inside(R.head_roll_deg, b.head_roll_deg) && inside(R.noise_scale, b.noise_scale));
		assert_true(inside(R.ambient_pattern, b.rig.lighting.ambient_pattern));
		assert_true(inside(R.ambient_texture, b.rig.lighting.ambient_texture));
		assert_true(inside(R.read_noise_e, b.rig.sensor.read_noise_e));
		assert_true(inside(R.full_well_e, b.rig.sensor.full_well_e));
	}
	std::printf("  %d booths: %d masked; projector quarter turns %d / %d / %d / %d; cell pitch in the images "
		    "%.0f..%.0f px\n",
		    n, masked, quarter[0], quarter[1], quarter[2], quarter[3], img_pitch_lo, img_pitch_hi);
	assert_true(masked > n / 3 && masked < 2 * n / 3);
	for (int q : quarter)
		assert_true(q > 3 * n / 4 / 2); // each quarter turn drawn about a quarter of 3n times
	RandomBooth b;
	assert_int_equal(random_booth(1, 0, &b).code(), -EINVAL);
}

static void test_same_seed_same_booth(void **)
{
	const double pitch_px = slide_pitch();
	RandomBooth a, b, c;
	assert_true(random_booth(5, pitch_px, &a).ok());
	assert_true(random_booth(5, pitch_px, &b).ok());
	assert_true(random_booth(6, pitch_px, &c).ok());
	double diff = 0;
	for (size_t i = 0; i < 4; i++) {
		const CameraModel &x = a.rig.cameras[i].model, &y = b.rig.cameras[i].model;
		assert_true(cv::norm(x.K - y.K) == 0 && cv::norm(x.R - y.R) == 0 && cv::norm(x.T - y.T) == 0);
		assert_true(cv::norm(x.dist - y.dist) == 0 && x.size == y.size);
		diff += cv::norm(x.T - c.rig.cameras[i].model.T);
	}
	for (size_t j = 0; j < 3; j++) {
		assert_true(cv::norm(a.rig.projectors[j].K - b.rig.projectors[j].K) == 0);
		assert_true(a.rig.projectors[j].mask == b.rig.projectors[j].mask);
	}
	assert_true(a.head_offset_mm == b.head_offset_mm && a.head_yaw_deg == b.head_yaw_deg);
	std::printf("  seed 5 twice: identical; seed 6: cameras moved by %.0f mm in all\n", diff);
	assert_true(diff > 10);
}

static void test_calibration_error(void **)
{
	const double pitch_px = slide_pitch();
	HeadSpec hs;
	hs.cell_mm = 4.0; // coarse: only its points matter
	Mesh head;
	assert_true(make_head(hs, cv::Vec3f(0.6f, 0.4f, 0.3f), &head).ok());
	for (uint64_t seed : {1, 2, 3}) {
		RandomBooth b;
		assert_true(random_booth(seed, pitch_px, &b).ok());
		std::vector<cv::Point3d> pts;
		for (const cv::Vec3f &v : head.vertices)
			pts.emplace_back(v[0] + b.head_offset_mm[0], v[1] + b.head_offset_mm[1], v[2] + b.head_offset_mm[2]);
		const Calibration truth = rig_calibration(b.rig);
		Calibration written, again;
		std::vector<double> rms, rms2;
		assert_true(perturb_calibration(truth, b.calibration_error_px, pts, seed, &written, &rms).ok());
		assert_true(perturb_calibration(truth, b.calibration_error_px, pts, seed, &again, &rms2).ok());
		for (size_t i = 0; i < 4; i++) {
			const CameraModel &t = truth.cameras[i], &w = written.cameras[i];
			const double measured = reprojection_rms(t, w, pts);
			cv::Vec3d rv;
			cv::Rodrigues(w.R * t.R.t(), rv);
			const double df = std::fabs(w.K(0, 0) / t.K(0, 0) - 1), dc = std::hypot(w.K(0, 2) - t.K(0, 2), w.K(1, 2) - t.K(1, 2));
			const double dT = cv::norm(w.T - t.T), drot = cv::norm(rv) * 180 / M_PI;
			std::printf("  seed %llu cam%zu: target %.3f px, reached %.3f px (fx %.4f %%, c %.2f px, "
				    "R %.4f deg, T %.3f mm)\n",
				    (unsigned long long)seed, i, b.calibration_error_px[i], measured, 100 * df, dc, drot, dT);
			assert_true(std::fabs(measured - b.calibration_error_px[i]) <= 0.02 * b.calibration_error_px[i]);
			assert_true(std::fabs(rms[i] - measured) < 1e-9);
			// A good calibration's error: small in every parameter, but not zero.
			assert_true(df < 0.01 && dc < 5 && drot < 0.3 && dT < 3);
			assert_true(cv::norm(w.K - t.K) + cv::norm(w.dist - t.dist) + dT > 0);
			assert_true(cv::norm(w.K - again.cameras[i].K) == 0 && cv::norm(w.T - again.cameras[i].T) == 0);
		}
	}
	Calibration out;
	assert_int_equal(perturb_calibration(Calibration(), {0.3}, {}, 1, &out, nullptr).code(), -EINVAL);
}

// Two cameras and one masked projector in front of a wall: the renderer lights only inside the
// mask, and the evaluation counts as lit exactly the wall points inside it, also after the
// mask went through ground_truth_projectors.yaml.
static void test_masks_rendered_and_evaluated(void **)
{
	Surface wall;
	wall.mesh = make_plane(400, 400, 80);
	wall.id = 1;
	wall.albedo = cv::Vec3f(0.7f, 0.7f, 0.7f);
	Rig rig;
	for (double x : {-120.0, 120.0}) {
		SimCamera c;
		c.name = "cam";
		c.model.size = cv::Size(320, 240);
		c.model.K = cv::Matx33d(330, 0, 159.5, 0, 330, 119.5, 0, 0, 1);
		look_at(cv::Vec3d(x, 0, 600), cv::Vec3d(0, 0, 0), 0, &c.model.R, &c.model.T);
		c.focus_mm = 600;
		rig.cameras.push_back(c);
	}
	rig.sensor.bayer = false;
	rig.lighting.lights.clear();
	SimProjector pr;
	pr.name = "proj0";
	pr.K = cv::Matx33d(1200, 0, 511.5, 0, 1200, 383.5, 0, 0, 1);
	look_at(cv::Vec3d(0, 80, 700), cv::Vec3d(0, 0, 0), 30, &pr.R, &pr.T);
	pr.power = 1.5;
	// A slanted quadrilateral on the slide, cutting it well inside.
	pr.mask = {{100, 50}, {600, 120}, {520, 700}, {150, 650}};
	rig.projectors.push_back(pr);
	// A second one behind the wall lights none of it (calibration files hold >= 2 devices).
	SimProjector back = pr;
	back.name = "proj1";
	back.mask.clear();
	look_at(cv::Vec3d(0, 0, -700), cv::Vec3d(0, 0, 0), 0, &back.R, &back.T);
	rig.projectors.push_back(back);

	cv::Mat white(768, 1024, CV_8UC3, cv::Scalar(255, 255, 255));
	RenderOptions opt;
	opt.texture = false;
	opt.noise = false;
	opt.truth = true;
	RenderResult res;
	assert_true(render_views(rig, {wall}, white, opt, 1, &res).ok());
	int lit_in = 0, dark_out = 0, bad_in_truth = 0, bad_in_image = 0, bad_out_truth = 0, bad_out_image = 0;
	int dim = 255, bright = 0;
	for (size_t ci = 0; ci < 2; ci++) {
		const ViewTruth &t = res.truth[ci];
		cv::Mat gray;
		cv::cvtColor(res.frames[ci], gray, cv::COLOR_BGR2GRAY);
		for (int y = 0; y < 240; y++)
			for (int x = 0; x < 320; x++) {
				if (t.surface.at<uint8_t>(y, x) != 1)
					continue;
				cv::Vec3d o, d;
				pixel_ray(rig.cameras[ci].model, cv::Point2d(x, y), &o, &d);
				const cv::Vec3d w = o + d * (-o[2] / d[2]);
				const double m = polygon_test(pr.mask, slide_xy(pr, w));
				// The edge: the projector's defocus (the blurred slide reaches ~8 slide px) and a
				// camera pixel spanning ~3 slide px.
				if (std::fabs(m) < 12)
					continue;
				const bool truth_lit = t.projector.at<int8_t>(y, x) == 0;
				const int v = gray.at<uint8_t>(y, x);
				if (m > 0) {
					lit_in++;
					bad_in_truth += !truth_lit;
					bad_in_image += v < 100;
					dim = std::min(dim, v);
				} else {
					dark_out++;
					bad_out_truth += truth_lit;
					bad_out_image += v > 60;
					bright = std::max(bright, v);
				}
			}
	}
	const int bad = bad_in_truth + bad_in_image + bad_out_truth + bad_out_image;
	std::printf("  mask: %d wall pixels inside (darkest %d), %d outside (brightest %d); disagreements: "
		    "truth %d / %d, image %d / %d (inside / outside)\n",
		    lit_in, dim, dark_out, bright, bad_in_truth, bad_out_truth, bad_in_image, bad_out_image);
	assert_true(lit_in > 2000 && dark_out > 2000);
	assert_int_equal(bad, 0);

	// Through the files a simulated set writes, then the evaluation.
	char tmpl[] = "/tmp/facescan-booth-XXXXXX";
	assert_non_null(mkdtemp(tmpl));
	const std::string dir = tmpl;
	CaptureSet set;
	set.calibration = rig_calibration(rig);
	set.frames = res.frames;
	set.meta.scan_id = "test-mask";
	set.meta.pattern_id = "white";
	SimTruth truth;
	truth.head = wall.mesh;
	truth.projectors = projector_models(rig);
	truth.projector_masks = projector_masks(rig);
	assert_true(write_simulated_set(dir, set, truth).ok());
	recon::Mesh gt;
	std::vector<CameraModel> projectors;
	std::vector<std::vector<cv::Point2d>> masks;
	const Status st = eval::read_ground_truth(dir, &gt, &projectors, &masks);
	assert_int_equal(system(("rm -rf '" + dir + "'").c_str()), 0);
	if (!st.ok())
		std::printf("  %s\n", st.message().c_str());
	assert_true(st.ok());
	assert_int_equal(masks.size(), 2);
	assert_true(masks[1].empty());
	assert_int_equal(masks[0].size(), pr.mask.size());
	for (size_t k = 0; k < pr.mask.size(); k++)
		assert_true(cv::norm(masks[0][k] - pr.mask[k]) < 1e-3);

	eval::EvalParams whole, masked;
	masked.projector_masks = masks;
	eval::EvalResult rw, rm;
	assert_true(eval::evaluate(gt, gt, set.calibration.cameras, projectors, whole, &rw).ok());
	assert_true(eval::evaluate(gt, gt, set.calibration.cameras, projectors, masked, &rm).ok());
	int inside_counted = 0, wrong = 0;
	for (size_t i = 0; i < gt.positions.size(); i++) {
		const cv::Vec3d p(gt.positions[i].x, gt.positions[i].y, gt.positions[i].z);
		const double m = polygon_test(pr.mask, slide_xy(pr, p));
		if (std::fabs(m) < 0.01)
			continue;
		const bool counted_whole = rw.truth_status[i] >= 0, counted = rm.truth_status[i] >= 0;
		wrong += counted != (counted_whole && m > 0);
		inside_counted += counted;
	}
	std::printf("  evaluate: %d truth points counted with the whole slide, %d through the mask; %d wrong\n",
		    rw.truth_counted, rm.truth_counted, wrong);
	assert_int_equal(wrong, 0);
	assert_true(rm.truth_counted > 500 && rm.truth_counted < rw.truth_counted * 0.8);
	assert_true(rm.completeness > 0.99);
	eval::EvalParams too_many;
	too_many.projector_masks.resize(3);
	assert_int_equal(eval::evaluate(gt, gt, set.calibration.cameras, projectors, too_many, &rm).code(), -EINVAL);
}

static void test_booth_file_round_trip(void **)
{
	RandomBooth b;
	for (uint64_t seed = 1; seed < 40; seed++) { // find a masked booth
		assert_true(random_booth(seed, slide_pitch(), &b).ok());
		if (b.masked)
			break;
	}
	assert_true(b.masked);
	char path[] = "/tmp/facescan-booth-XXXXXX";
	int fd = mkstemp(path);
	assert_true(fd >= 0);
	close(fd);
	assert_true(write_rig(path, b.rig, booth_yaml(b, b.calibration_error_px)).ok());
	Rig back;
	Status st = load_rig(path, &back);
	if (!st.ok())
		std::printf("  %s\n", st.message().c_str());
	unlink(path);
	assert_true(st.ok());
	assert_int_equal(back.cameras.size(), 4);
	assert_int_equal(back.projectors.size(), 3);
	for (size_t i = 0; i < 4; i++) {
		const CameraModel &x = b.rig.cameras[i].model, &y = back.cameras[i].model;
		assert_true(cv::norm(x.K - y.K) < 1e-9 && cv::norm(x.R - y.R) < 1e-12 && cv::norm(x.T - y.T) < 1e-9);
		assert_true(cv::norm(x.dist - y.dist) < 1e-12 && x.size == y.size);
		assert_true(std::fabs(b.rig.cameras[i].exposure - back.cameras[i].exposure) < 1e-12);
	}
	for (size_t j = 0; j < 3; j++) {
		const SimProjector &x = b.rig.projectors[j], &y = back.projectors[j];
		assert_true(cv::norm(x.K - y.K) < 1e-9 && cv::norm(x.centre() - y.centre()) < 1e-9);
		assert_true(std::fabs(x.power - y.power) < 1e-12);
		assert_int_equal(x.mask.size(), y.mask.size());
		for (size_t k = 0; k < x.mask.size(); k++)
			assert_true(cv::norm(x.mask[k] - y.mask[k]) < 1e-9);
	}
	assert_true(std::fabs(back.lighting.ambient_pattern - b.rig.lighting.ambient_pattern) < 1e-12);
	assert_true(std::fabs(back.sensor.read_noise_e - b.rig.sensor.read_noise_e) < 1e-12);
}

static void test_head_family(void **)
{
	const auto &ranges = head_look_ranges();
	HeadLook canonical;
	for (const HeadLookRange &r : ranges) {
		double c = canonical.*r.member;
		assert_true(c >= r.lo && c <= r.hi); // the canonical look is a member of the family
	}
	double tone_lo = 1, tone_hi = 0, lum_lo = 1, lum_hi = 0;
	int shoulders = 0, stubble = 0, freckled = 0;
	for (uint64_t seed = 0; seed < 300; seed++) {
		HeadAppearance a = random_head_appearance(seed);
		for (const HeadLookRange &r : ranges) {
			double v = a.look.*r.member;
			assert_true(v >= r.lo && v <= r.hi);
		}
		tone_lo = std::min(tone_lo, a.skin_tone);
		tone_hi = std::max(tone_hi, a.skin_tone);
		double lum = 0.2126 * a.skin[0] + 0.7152 * a.skin[1] + 0.0722 * a.skin[2];
		lum_lo = std::min(lum_lo, lum);
		lum_hi = std::max(lum_hi, lum);
		shoulders += a.look.shoulders;
		stubble += a.look.stubble > 0;
		freckled += a.look.freckles > 0.3;
	}
	std::printf("  300 looks: skin luminance %.3f..%.3f, %d with shoulders, %d stubbled, %d freckled\n", lum_lo,
		    lum_hi, shoulders, stubble, freckled);
	assert_true(tone_lo < 0.05 && tone_hi > 0.95);
	assert_true(lum_lo < 0.09 && lum_hi > 0.45); // from the "dark" scene's skin to lighter than canonical
	assert_true(shoulders > 150 && shoulders < 290 && stubble > 90 && stubble < 210 && freckled > 20);

	// A head with shoulders is closed and reaches below the neck's old cut; its look changes
	// the albedo, not the shape.
	HeadSpec spec;
	spec.cell_mm = 3.0;
	Mesh plain, styled, wide;
	assert_true(make_head(spec, cv::Vec3f(0.5f, 0.35f, 0.28f), &plain).ok());
	HeadAppearance a = random_head_appearance(11);
	a.look.shoulders = false;
	spec.look = a.look;
	assert_true(make_head(spec, a.skin, &styled).ok());
	assert_int_equal(plain.vertices.size(), styled.vertices.size());
	double dcol = 0;
	for (size_t i = 0; i < plain.vertices.size(); i++) {
		assert_true(plain.vertices[i] == styled.vertices[i]);
		dcol += cv::norm(plain.colors[i] - styled.colors[i]);
	}
	assert_true(dcol > 1);
	spec.look.shoulders = true;
	assert_true(make_head(spec, a.skin, &wide).ok());
	float ylo = 1e9f, xhi = -1e9f;
	for (const cv::Vec3f &v : wide.vertices) {
		ylo = std::min(ylo, v[1]);
		xhi = std::max(xhi, v[0]);
	}
	std::map<std::pair<int, int>, int> edges;
	for (const cv::Vec3i &t : wide.triangles)
		for (int k = 0; k < 3; k++) {
			int u = t[k], w = t[(k + 1) % 3];
			edges[{std::min(u, w), std::max(u, w)}]++;
		}
	size_t boundary = 0;
	for (const auto &e : edges)
		boundary += e.second == 1;
	std::printf("  shoulders: %zu triangles, lowest y %.0f mm, widest x %.0f mm, %zu boundary edges\n",
		    wide.triangles.size(), ylo, xhi, boundary);
	assert_true(ylo < -300 && xhi > 150);
	assert_int_equal(boundary, 0);
	spec.look.stubble = 3;
	assert_int_equal(make_head(spec, a.skin, &wide).code(), -EINVAL);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_ranges_honoured),
		cmocka_unit_test(test_same_seed_same_booth),
		cmocka_unit_test(test_calibration_error),
		cmocka_unit_test(test_masks_rendered_and_evaluated),
		cmocka_unit_test(test_booth_file_round_trip),
		cmocka_unit_test(test_head_family),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
