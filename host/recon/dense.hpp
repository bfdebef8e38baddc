// Stage D (dense): per consecutive camera pair, a sub-pixel correspondence for every lit pixel
// both cameras see, seeded and bounded by the code's sparse correspondences.
//
// The pair is rectified (OpenCV stereoRectify's rotations, our own intrinsics so that each
// camera's image centre stays in view however far the cameras converge). The triangulated sparse
// matches give a disparity at each code point; a piecewise-linear prior over their Delaunay
// triangulation (extended a little past its rim) says where every pixel's disparity lies. The
// second image is warped by that prior and OpenCV's semi-global matcher searches only a narrow
// residual range around it, so the search is cheap and cannot jump to another copy of the slide
// (a neighbouring square of the same colour is a whole square pitch away, beyond the residual).
// SGBM's own left-right check and speckle filter reject inconsistent pixels; a zero-mean NCC of
// the matched windows gives each point a confidence.
// Each pair is matched twice: the second time every pair's first points fill its prior where the
// code's triangles do not reach (`DenseParams::guided_pass`).
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "recon/types.hpp"

#include <opencv2/core.hpp>

#include <vector>

namespace facescan::recon {

struct DenseParams {
	/// Matching resolution relative to the cameras' (0.5: 800x600 for 1600x1200 cameras).
	double scale = 0.5;
	/// Residual search range, ± pixels at the matching resolution, around the prior.
	int residual_px = 8;
	/// Matches within this many pixels of the residual range's ends are dropped.
	float edge_margin_px = 1.0f;
	/// SGBM block size (odd) and smoothness penalties per channel (P1, P2 = factor * cn * block²).
	/// 3 with a 1 px unsure margin rather than 5 with 2 (2026-12-06, after the refinement's 13 px
	/// windows): held-out booths 2000-2011 RMS lower on 18 of 24 (mean -0.010 mm, 2000-scan
	/// 0.394 -> 0.347), face completeness +0.5 points on average (worst 2004-scan -2.2);
	/// bench booth 111 0.334 -> 0.258 mm. Block 3 alone lost completeness (111 -5.8 points):
	/// its matches are noisier at the edges SGBM refuses, and a 2 px margin cut too much there.
	int block = 3;
	int p1_factor = 8, p2_factor = 32;
	int uniqueness = 10;	    // SGBM uniqueness ratio, percent
	int disp12_max_diff = 1;    // left-right check, pixels at the matching resolution
	int speckle_window = 80;    // connected components smaller than this are dropped...
	int speckle_range = 2;	    // ... when they differ from their surroundings by more (px)
	/// Seed triangles whose longest side is at most `tight_edge_factor` median seed spacings give
	/// the prior; longer ones, up to `max_seed_edge_factor`, bridge holes and give it there only
	/// where the coarse search finds nothing.
	double tight_edge_factor = 4.0;
	double max_seed_edge_factor = 12.0;
	/// The coarse search (half the matching resolution, the seeds' whole disparity range) fills
	/// the prior where no small seed triangle reaches. With fewer than `min_seeds` seeds it is the
	/// whole prior, over the disparities of the working volume: `volume_depth_mm` along the
	/// cameras' axes and `volume_side_mm` across, around where the axes pass closest.
	bool coarse = true;
	/// It runs on the bounding box of the lit pixels the small triangles miss, plus this margin
	/// (half-resolution pixels) so that SGBM's aggregation paths start outside it.
	int coarse_margin_px = 32;
	double volume_depth_mm = 150, volume_side_mm = 120;
	/// The prior is extended past its rim by this many median seed spacings (nearest value).
	double extrapolate_spacings = 0.0;
	int min_seeds = 6;	    // fewer seeds: the code gives no prior (the coarse search alone does)
	/// Seeds whose small triangles cover less than this fraction of the lit pixels sit in one
	/// corner of the face (a pair that decodes a patch of the chin), and their disparities say
	/// nothing of the rest: the coarse search then spans the working volume's disparities as well
	/// as theirs. Below 3 % in 21 bench and 24 fresh scenes (3200-3223): bench booth 103-head1032
	/// (two pairs, 1.6 and 2.5 %) 70.6 -> 80.2 % face completeness, fresh 3220 (0.8 %) 70.7 ->
	/// 89.5 % (RMS 0.209 -> 0.233 mm), 3203 +0.1, 111-head1112 -0.3, 3218 -1.6 points. Between 3
	/// and 5 % the wider range lost more than it won (3222 -11.9, 3111 -2.3, 3215 +0.1): hence
	/// the limit. 0: the seeds' range only.
	double min_seed_cover = 0.03;
	/// Each pair is matched twice: the second time its prior is, where the code's small triangles
	/// give none, every pair's first points (its own too) seen from it — one per `guide_cell_px`
	/// cell of its rectified left view, the nearest, linearly interpolated over triangles at most
	/// `guide_edge_factor` cells long — and the coarse search only where those do not reach.
	/// A point more than `guide_hidden_px` of disparity behind the nearest in its cell of the
	/// right view is hidden from the right camera and not used (60 scenes, bench 12 and fresh
	/// 6400-6411, 5600-5611: RMS mean -0.0067, -0.0023, -0.0033 mm, completeness +0.29, -0.12,
	/// -0.02 points; bench 111-head1111 0.297 -> 0.245 mm; on 111-head1110 the guide had put 430
	/// points of pair 2-3 on a cheek camera 3 does not see, 45 % of them > 1 mm off; 1 and 4 px
	/// alike).
	bool guided_pass = true;
	int guide_cell_px = 6;
	double guide_edge_factor = 3.0;
	double guide_hidden_px = 2.0;
	/// Pixels darker than this (0-255 grey, pattern frame, either view) are unlit: not matched.
	int min_intensity = 12;
	/// Pixels whose grey standard deviation over a window of `contrast_window_pitches` square
	/// pitches (twice the median seed spacing; `default_pitch_px` without seeds) is below this
	/// are not under the pattern: not matched.
	double min_pattern_contrast = 6;
	double contrast_window_pitches = 1.5;
	double default_pitch_px = 16;
	/// Points whose NCC over the block is below this are dropped (0..1).
	double min_confidence = 0.5;
	/// The confidence of a point whose window has no texture (inside a flat square, where SGBM's
	/// smoothness carries the disparity in from the square's edges and NCC says nothing). Flat
	/// points are about twice as far off the surface as textured ones (RMS 0.81 against 0.44 mm
	/// on a bench scene with 18 mm squares), so where pairs overlap the textured sample leads.
	double flat_confidence = 0.2;
	/// Flat regions (windows whose grey standard deviation over the block is at most
	/// `flat_texture_std`) are refilled from the textured matches on a ring of `flat_ring_px`
	/// around them where those agree with one quadratic to `flat_max_fit_px` (fill_flat_regions).
	bool flat_fill = true;
	double flat_texture_std = 4;
	int flat_ring_px = 3;
	int flat_min_ring = 24;
	/// 0.5 before 2026-12-07: on booths whose cameras see the face at 0.35-0.5 mm a pixel (the
	/// matching pixel twice that), the rings of about half the bright flat area missed it
	/// (fresh booth 4811: their last fit 0.5 px RMS at the median, with 98 % of the ring inside
	/// the gate) and kept SGBM's values, the largest part of the squared error there (flat
	/// points 37-54 % of a pair's cloud, 57-77 % of its squared error, 0.43-0.77 mm RMS against
	/// 0.29-0.43 textured). With `flat_max_overshoot_px`, on 96 scenes (4100-4111, 4200-4211,
	/// 4800-4811 and, not looked at before, 5000-5011; both heads): RMS mean -0.0055, -0.0026,
	/// -0.0050 and -0.0034 mm (higher on 4-9 scenes of each 24, by at most 0.019), face
	/// completeness +0.90, +0.99, +1.13 and +0.71 points (lower on 1-2 of each 24, by at most 0.8).
	/// The price: a ramp now fits the ring of a square split by a 4 px step (test_dense); an 8 px
	/// one it does not. Asking 85 % of the ring at 1 px (and 70 % at 0.5) kept the 4 px step out
	/// but halved what was won.
	double flat_max_fit_px = 1.0;
	double flat_min_inliers = 0.7; // of the ring: a ring split by a step fits one side only
	/// A fitted quadratic that leaves its ring's range (the inliers' disparities) by more than this
	/// anywhere in the region is not used: where the ring is one-sided (a square cut by the edge of
	/// the match) the quadratic is free on the open side (fresh booth 4807 with the scanned head,
	/// without it: a patch 5-9 mm off, RMS 0.317 -> 0.372 mm). A face's curve inside one square
	/// stays well within a pixel of its edges' range. Negative: not checked.
	double flat_max_overshoot_px = 1.0;
	/// Dark flat regions (darker than their ring: the gaps between the squares) of more than this
	/// squared are also fitted piecewise, on a grid of this many pixels, each piece from its share
	/// of the ring; a piece whose own ring fits no quadratic takes the whole region's fit. Where
	/// the gaps join into one lattice around many squares, no quadratic follows it whole (fresh
	/// booth 4811: 20 dark regions of 34.5k px, fit RMS 2.3 px) and SGBM's guess stayed.
	/// 2026-12-07, both heads, RMS mean: -0.0067 mm on 4800-4811 (tuned on), -0.0080 on
	/// 4100-4111, -0.0045 on 4200-4211, -0.0043 on 5000-5011, -0.0061 on 5200-5211 and -0.0085
	/// on 5600-5611 (higher on 2-4 of each 24, by at most 0.009); face completeness +0.80, +0.48,
	/// +0.58, +0.35, +0.23 and +0.55 points (lower on 2-5, by at most 1.9). Bright regions cut
	/// too lost on bench booth 111 (RMS +0.002 to +0.020 mm on its four scenes: pieces fitted to
	/// short stretches of edge near the match's border keep what the unfitted reach would drop).
	/// Dark regions only: 16 and 32 px are within 0.002 mm of 24 (RMS mean on 4800-4811 and
	/// 5600-5611); cutting bright regions too, 16 px lost on booths of every pitch (+0.004 mm on
	/// 4800-4811), so the size is in pixels, not pitches. 0: whole regions only.
	int flat_tile_px = 24;
	/// A flat region darker than its ring (a gap, a shadow, the band between two projectors'
	/// zones: no lit square) keeps its pixels only within this many pixels of a textured match;
	/// farther, nothing in the pattern supports SGBM's guess and they are dropped. 0: kept.
	double flat_dark_reach_px = 5;
	/// A bright flat region whose ring fits no quadratic (a mismatched edge, a ring cut open by
	/// the matched region's border) keeps SGBM's values only within this many pixels of a
	/// textured match: deeper inside, SGBM's smoothness has carried a disparity in along a few
	/// path directions from edges that disagree (random booths 111, 604: such points near the
	/// pair's border RMS 0.7-0.8 mm, one in ten > 1 mm off). 0: kept.
	double flat_unfitted_reach_px = 8;
	/// Dark gaps bridged: on a dim booth the black gaps between the squares fall below
	/// `min_intensity` and stay unmatched, so the matched region is a lattice of squares that the
	/// rim and island filters cut apart (held-out booth 1604 with the scanned head: 16 % of the
	/// counted face lost as dark, 19 % as rim, 13 % as islands; completeness 38 %). A dark pixel
	/// with a prior, inside a gap of the matched region at most `dark_bridge_pitches` square
	/// pitches wide (the slide's gaps are 0.3), gets the quadratic fitted to the matches within
	/// `dark_bridge_fit_pitches` of it when, after two trimmed refits, ≥ 70 % of them agree with it
	/// to `dark_bridge_max_fit_px` RMS, those lie on every side of it (each quadrant), and the fit
	/// bends by at most `dark_bridge_max_bend_px` at the window's edge (a gap across a step, a
	/// shadow beside the nose, fits only with a sharp bend). Its point carries `flat_confidence`.
	/// 0: off.
	double dark_bridge_pitches = 0.45;
	double dark_bridge_fit_pitches = 0.25;
	double dark_bridge_max_fit_px = 0.3;
	double dark_bridge_max_bend_px = 2.0;
	/// Matches within this many pixels (square neighbourhood, matching resolution) of a prior pixel
	/// SGBM refused (its checks found no match) are dropped: they border a mismatch or an
	/// occlusion. Pixels next to ones only too dark to match (the gaps between squares on a dim
	/// booth) stay. 0: off.
	int unmatched_margin_px = 1;
	/// Connected matched regions smaller than this (pixels, matching resolution) are dropped.
	int min_region_px = 400;
	/// Pixels where the disparity changes faster than this (px per px: ~66 degrees of slant at the
	/// default booth) and their neighbours are dropped; so is a rim of `rim_px` pixels.
	double max_disparity_gradient = 1.5;
	/// ... except along the rows where the disparity falls (d = x_a - x_b): a surface there is
	/// stretched in the second view, seen more frontally by it than by the first (a slope of -3
	/// makes it 4 times as wide there), which the prior's warp has already taken up; only beyond
	/// this slope is it dropped. Rising along the rows is the other way (towards 1 the second
	/// view sees the surface edge-on; beyond 1 it could not see it at all) and keeps the limit
	/// above. 10 fresh random booths (1510-1519): completeness up on 9, median +0.38 points
	/// (1514 54.2 -> 57.0 %), RMS median +0.001 mm (at most +0.003).
	double max_falling_gradient = 3.0;
	/// 2 before 2026-12-06: the fused surface's own outline trim (SurfaceParams::trim_border_cells)
	/// now takes the rest, where only the union's border is left. Bench booths 101-112 (head 0 and
	/// scan) and fresh 3100-3111: RMS lower on 19 of 24 and 12 of 12 (mean -0.009 mm both),
	/// face completeness mean -0.02 and -0.24 points.
	int rim_px = 1;
	int pinhole_px = 60; // unmatched holes up to this size do not count as rim
	/// Sub-pixel refinement after SGBM: Lucas-Kanade along the rows at `refine_scale` times the
	/// matching resolution (2: the cameras' own), zero-mean windows of `refine_window` pixels,
	/// where the window's mean squared gradient exceeds `refine_min_gradient`² (a flat square's
	/// interior keeps SGBM's value). 0 iterations: off. Two iterations of 13 px rather than
	/// three of 9: RMS lower on 21 of 24 held-out scenes (booths 2000-2011, mean -0.007 mm,
	/// 2011-scan 0.257 -> 0.237) and 12 of 12 bench booths (104 0.344 -> 0.329, 105 0.267 ->
	/// 0.239), completeness within run-to-run noise, a third less refinement time. A third
	/// iteration moved points away from the truth more often than towards it.
	int refine_iterations = 2;
	double refine_scale = 2.0;
	int refine_window = 13;
	double refine_min_gradient = 2.0;
	/// Points at the refinement's resolution: a matched pixel whose refinement_scale² camera
	/// pixels the refinement measured (each its own Lucas-Kanade window) gives one point for each
	/// of them, not one for the matching pixel; a pixel it did not measure (a flat square's
	/// interior, a refilled or bridged one) gives its one point as before. No point is
	/// interpolated. false: one point per matched pixel.
	bool points_at_refine_scale = true;
};

/// One pair's dense points, world mm (before registration moves them).
struct DenseCloud {
	int cam_a = -1, cam_b = -1;
	std::vector<cv::Point3f> points;
	std::vector<float> confidence; // NCC of the matched windows, 0..1
	std::vector<float> border_mm;  // distance to the border of the pair's matched region
};

struct DenseStats {
	int seeds = 0;	       // sparse points used
	int prior_pixels = 0;  // pixels with a prior (matching resolution)
	int coarse_pixels = 0; // ... of which the coarse search gave the prior
	int guided_pixels = 0; // ... of which the pairs' first points gave it (the guided pass)
	double seed_cover = 0;	// fraction of the lit pixels the seeds' small triangles cover
	bool coarse_over_volume = false; // the coarse search spanned the working volume's disparities
	int unlit = 0;	       // prior pixels dropped as not under the pattern
	int matched = 0;       // pixels SGBM matched inside the prior
	int low_confidence = 0; // dropped by NCC
	int near_unmatched = 0; // dropped: within unmatched_margin_px of a pixel SGBM refused
	int islands = 0;	// dropped as part of a small matched region
	int at_search_edge = 0; // dropped: matched at the end of the residual range
	int steep = 0, rim = 0; // dropped: steep disparity, the matched region's rim
	int flat_filled = 0, flat_kept = 0; // flat-region pixels refilled / left as SGBM matched them
	int flat_dropped = 0;		    // ... dropped: dark and out of the texture's reach
	int flat_unfitted_dropped = 0;	    // ... dropped: bright, unfitted, out of the texture's reach
	int dark_bridged = 0;		    // dark pixels inside a gap of the matches, given their quadratic
	int points = 0;	       // in the cloud
	double median_spacing_px = 0; // of the seeds, matching resolution
};

/// `mask` (CV_8U, 0 or 255) eroded by `iterations` steps of the 3 × 3 `shape` (cv::MORPH_RECT or
/// cv::MORPH_CROSS) along its outline only: its holes of at most `pinhole_px` pixels (4-connected)
/// count as inside, so they are not widened. The result lies within `mask`. The pairs' rim and the
/// fused surface's outline are trimmed with it.
cv::Mat erode_outline(const cv::Mat &mask, int pinhole_px, int iterations, int shape);

/// Inside a flat square SGBM has nothing to match: its smoothness carries a disparity in from the
/// square's edges along its few path directions, and the interior ends up tilted or offset (bench
/// booth 111: flat points RMS 0.81 mm, textured 0.44). Each flat region (4-connected `valid` pixels
/// whose `std_l`, the grey standard deviation over the block, is at most `flat_texture_std`) gets
/// instead the quadratic d = f(x, y) fitted to the textured matches within `flat_ring_px` of it
/// (the square's own edges) — least squares, then twice again on the ring pixels within 2× and 1×
/// `flat_max_fit_px` of the last fit — when at least `flat_min_ring` pixels and `flat_min_inliers`
/// of its ring survive with an RMS of at most `flat_max_fit_px` and the fit stays within
/// `flat_max_overshoot_px` of the inliers' range over the whole region. A dark region (below) of
/// more than `flat_tile_px`² pixels is also cut by a grid of `flat_tile_px` into pieces, each
/// fitted the same way from the ring pixels within `flat_ring_px` of it; a piece takes its own fit
/// where it has one, its region's otherwise. Other regions (a ring that fits no quadratic: a large
/// unpatterned patch, a mismatch at the edge, a one-sided ring) keep SGBM's values — except that a
/// region darker in `grey_l` than its ring (no lit square: a gap, a shadow, the band between
/// projector zones) loses its pixels farther than `flat_dark_reach_px` from any textured match, and
/// a bright one whose ring fits no quadratic those farther than `flat_unfitted_reach_px` (cleared
/// in `valid`). `total` is the disparity (CV_32F), `valid` the matched mask (CV_8U), `grey_l` the
/// left view (CV_8U). Returns the pixels refilled; counts them, the kept and the dropped ones
/// (`flat_dropped` dark, `flat_unfitted_dropped` bright and unfitted) in `stats`.
int fill_flat_regions(const cv::Mat &grey_l, const cv::Mat &std_l, const DenseParams &params, cv::Mat *valid,
		      cv::Mat *total, DenseStats *stats);

/// The dark gaps of the matched region bridged (DenseParams::dark_bridge_pitches): each `dark`
/// pixel (CV_8U, nonzero: too dark to match, with a prior) that a closing of `valid` by a disk
/// `dark_bridge_pitches` × `pitch_px` wide covers gets the quadratic d = f(x, y) least-squares
/// fitted to the `valid` disparities of `total` within `dark_bridge_fit_pitches` × `pitch_px`
/// (refitted twice on the samples within 2× and 1× `dark_bridge_max_fit_px` of the last fit),
/// when at least 24 samples and 70 % of them stay, fitting it to `dark_bridge_max_fit_px` RMS,
/// at least 3 of those in each quadrant around the pixel, and the fit's second-order part is at
/// most `dark_bridge_max_bend_px` (|c_uu| + |c_uv| / 2 + |c_vv|, u and v in units of the
/// window's radius); it is then set in `valid` and `bridged` (CV_8U, same size, allocated here).
/// Returns the pixels bridged.
int bridge_dark_gaps(const cv::Mat &dark, double pitch_px, const DenseParams &params, cv::Mat *valid, cv::Mat *total,
		     cv::Mat *ret_bridged);

/// Why a rectified left pixel has no point in the pair's cloud (DensePairDebug::reason), in the
/// stages' order: the last stage that looked at it. `facescan evaluate --missing` reads them.
enum DenseReason : unsigned char {
	kReasonNoPrior = 1,	   // outside the seeds' triangles and the coarse search's matches
	kReasonUnlit = 2,	   // a prior, but not under the pattern (grey contrast)
	kReasonRefused = 3,	   // SGBM's left-right, uniqueness or speckle check refused it
	kReasonDark = 4,	   // below min_intensity in either view
	kReasonLowConfidence = 5,  // NCC < min_confidence
	kReasonSearchEdge = 6,	   // at the residual range's end
	kReasonNearRefused = 7,	   // within unmatched_margin_px of a refused pixel
	kReasonFlatDropped = 8,	   // a flat region's pixel out of the texture's reach
	kReasonRim = 9,		   // the matched region's rim
	kReasonSteep = 10,	   // steep disparity
	kReasonIsland = 11,	   // a small matched region
	kReasonKept = 12,	   // in the cloud
};

/// What dense_pair saw, for `recon --debug`: the rectified left view, the right view warped by the
/// prior (where the prior is right, the two line up), the prior and the final disparity (CV_32F,
/// NaN where none); per pixel the DenseReason (CV_8U) and the projection of a world point (mm,
/// before registration) into the rectified left view.
struct DensePairDebug {
	cv::Mat left, warped, prior, disparity, reason;
	cv::Matx34d world_to_left;
};

/// Rectification of a pair at a matching scale: rotations R1, R2 (camera → rectified), shared
/// focal f and row centre cy, per-camera column centres, the baseline along the rectified x axis
/// (mm, b's centre in a's rectified frame) and the maps for cv::remap.
struct RectifiedPair {
	cv::Matx33d R1, R2;
	double f = 0, cx1 = 0, cx2 = 0, cy = 0, baseline = 0;
	cv::Size size;
	cv::Mat map1x, map1y, map2x, map2y; // CV_32F
};

/// 255 where a CV_32F map has a value, 0 where it is NaN.
cv::Mat has_value(const cv::Mat &map);

/// Builds the rectification of cameras a, b at `scale`. -EINVAL for a degenerate pair.
Status rectify_pair(const CameraModel &a, const CameraModel &b, double scale, RectifiedPair *ret);

/// Rectified coordinates of distorted pixels of camera a (which = 0) or b (which = 1).
std::vector<cv::Point2d> rectify_points(const RectifiedPair &rp, const CameraModel &cam, int which,
					const std::vector<cv::Point2d> &pixels);

/// World point of rectified left pixel (x, y) with disparity d = x_a - x_b (rectified pixels).
cv::Point3d rectified_to_world(const RectifiedPair &rp, const CameraModel &a, double x, double y, double d);

/// Piecewise-linear disparity prior over the seeds (rectified left pixel → disparity): CV_32F,
/// NaN where there is none. Exposed for tests.
/// Triangles longer than `max_edge_factor` median seed spacings are left out; past the rim the
/// nearest value reaches `extrapolate_spacings` spacings.
cv::Mat disparity_prior(cv::Size size, const std::vector<cv::Point2d> &seeds_left,
			const std::vector<double> &seed_disparity, double max_edge_factor, double extrapolate_spacings,
			double *ret_median_spacing_px);

/// The steep filter's verdict (CV_8U, 255 = steep) on `disparity` (CV_32F) where `valid`: the
/// central difference over 2 px rises by more than 2 * max_disparity_gradient along the rows or
/// changes by more than that down the columns, or falls by more than 2 * max_falling_gradient
/// along the rows (DenseParams). Exposed for tests.
cv::Mat steep_pixels(const cv::Mat &valid, const cv::Mat &disparity, const DenseParams &params);

/// The refinement's own measurements at its resolution: pixel (u, v) of `disparity` is the
/// camera-resolution pixel at matching coordinates (roi.x + u / scale, roi.y + v / scale); its
/// value is the disparity there in matching pixels, NaN where the refinement did not measure it.
struct RefinedDisparity {
	cv::Rect roi;	   // matching pixels refined
	int scale = 0;	   // camera pixels per matching pixel (0: none)
	cv::Mat disparity; // CV_32F, roi.size() * scale
};

/// What the refinement reads: both frames rectified again at `scale` times the matching
/// resolution (the same geometry scaled: refinement x = scale × matching x), grey (CV_8U). `left`
/// covers the matching pixels of `region`, from refinement pixel (region.x, region.y) × scale;
/// `right` the same rows over the rectified right view's whole width, from column 0, so that a
/// match reads it wherever its disparity lands.
struct RefineViews {
	cv::Rect region; // matching pixels
	double scale = 0;
	cv::Mat left, right;
};

/// The refinement's views of a pair over `region` (matching pixels; empty views when it is).
RefineViews refine_views(const cv::Mat &frame_a, const cv::Mat &frame_b, const CameraModel &a, const CameraModel &b,
			 const RectifiedPair &rp, double scale, cv::Rect region);

/// Refines `disparity` (rectified matching pixels, CV_32F, valid where `valid` != 0) in place by
/// Lucas-Kanade along the rows on `views` (over the valid pixels' bounding box within
/// views.region). With `ret_refined` (and an integer views.scale), also the refined disparity at
/// that scale.
void refine_subpixel(const RefineViews &views, const cv::Mat &valid, const DenseParams &params, cv::Mat *disparity,
		     RefinedDisparity *ret_refined = nullptr);

/// One pair made ready for matching (`prepare_pair`): what a match computes from the frames, the
/// cameras and the code's seeds alone, so that the guided pass (DenseParams::guided_pass) matches
/// the pair again without computing it again.
struct PreparedPair {
	DenseParams params;
	cv::Mat frame_b; // the right pattern frame (shared, not copied): warped and coarse-searched
	CameraModel a, b;
	int cam_a = -1, cam_b = -1;
	RectifiedPair rp;
	std::vector<cv::Point2d> seeds; // the code's matches in the rectified left view
	std::vector<double> seed_d;	// ... and their disparities
	cv::Mat left, grey_l, grey_l32; // the rectified left view (BGR, grey, grey CV_32F)
	cv::Mat lit;			// where the pattern falls (CV_8U)
	cv::Mat tight, loose; // the code's disparity over its small triangles, and its long ones too
	cv::Rect uncovered;   // bounding box of the lit pixels `tight` misses
	double median_spacing_px = 0; // of the seeds
	double seed_cover = 0;	      // fraction of the lit pixels `tight` covers
	RefineViews refine;	      // over the lit pixels' bounding box
};

/// Prepares one pair for `match_pair`. `model` is the pair's triangulated sparse model (its sources
/// give the seeds); frames are the pair's 8-bit BGR pattern frames. -EINVAL for frames that are
/// not, parameters out of range or a degenerate pair.
Status prepare_pair(const cv::Mat &frame_a, const cv::Mat &frame_b, const CameraModel &a, const CameraModel &b,
		    const PartialModel &model, const DenseParams &params, PreparedPair *ret);

/// Dense matching of a prepared pair, with its params. `guide`: dense points (world mm) that give
/// the prior where the code's small triangles do not (`DenseParams::guided_pass`), or nullptr.
Status match_pair(const PreparedPair &pair, const std::vector<cv::Point3f> *guide, DenseCloud *ret_cloud,
		  DenseStats *ret_stats, DensePairDebug *ret_debug = nullptr);

/// `prepare_pair`, then `match_pair`: one pair matched once.
Status dense_pair(const cv::Mat &frame_a, const cv::Mat &frame_b, const CameraModel &a, const CameraModel &b,
		  const PartialModel &model, const DenseParams &params, DenseCloud *ret_cloud,
		  DenseStats *ret_stats, DensePairDebug *ret_debug = nullptr,
		  const std::vector<cv::Point3f> *guide = nullptr);

} // namespace facescan::recon
