// Image side of the reconstruction (issue 3, stages 1-5): from one camera frame to decoded squares
// with sub-pixel corners, and from two cameras' detections to matched image points.
//
//   detect_squares(frame)  = intensity → find_squares → corners (force field + sub-pixel)
//                            → classify_letters (adaptive hue) → link_grid → decode_cells
//   match_pair(a, b)       = match_codes (same cell id + epipolar constraint + depth plausibility,
//                            one copy of the slide at a time: three projectors throw the same
//                            slide) → grow_matches → guide_matches → seed_matches → prune_matches
//
// Every sub-stage is a free function with its Params struct; none does I/O or logs.
// Image coordinates are distorted pixels with the OpenCV convention (pixel centres at integers).
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "pattern/pattern.hpp"
#include "recon/types.hpp"

#include <opencv2/core.hpp>

#include <array>
#include <vector>

namespace facescan::recon {

// ---- stage 1a: HSI ---------------------------------------------------------------------------

/// The paper's HSI planes, CV_32F, all on 0..255 (hue 0..255 ≙ 0..360°, 0 where saturation is 0).
struct HsiImage {
	cv::Mat h, s, i;
};
/// Whole-frame HSI conversion (Gonzalez & Woods). detect_squares only needs the intensity plane
/// and per-square colours, so it calls bgr_to_intensity and hsi_of_bgr instead.
Status bgr_to_hsi(const cv::Mat &bgr, HsiImage *ret_hsi);
/// I = (B + G + R) / 3 as CV_32F. With gamma != 1 the channels are first linearised,
/// 255 * (v / 255)^gamma: cameras encode their output with a gamma, and a blurred edge lies at
/// the midpoint level only in linear light.
Status bgr_to_intensity(const cv::Mat &bgr, cv::Mat *ret_intensity, double gamma = 1.0);
/// The 256-entry table v → 255 * (v / 255)^gamma.
std::array<float, 256> linear_table(double gamma);
/// HSI of one colour (B, G, R order, 0..255): hue 0..255, saturation 0..255, intensity 0..255.
cv::Vec3d hsi_of_bgr(const cv::Vec3d &bgr);

// ---- stage 1b: squares on intensity ----------------------------------------------------------

struct SquareParams {
	/// Side of the first-pass local-mean window in pixels; 0 = derive from the image size.
	int first_window_px = 0;
	/// Local-mean window for the final pass, in median square sides (0 = single pass).
	double window_sides = 3.0;
	/// Square accepted when its area is within [min, max] times the median square area.
	double min_area_ratio = 0.2, max_area_ratio = 3.0;
	double min_area_px = 25;	// absolute floor (noise specks)
	double min_solidity = 0.80;	// area / convex hull area
	/// Minimum contrast (inside - outside level) over the inside level.
	double min_contrast = 0.25;
	/// Blobs out of the area range, too big or too small, form another square size (mixed
	/// projector pitches) when at least this many; each such size gets its own pass. 0 = one
	/// size per image.
	int min_class_squares = 15;
};

/// A detected square's pixels: its binary mask inside `box`, and its local light levels.
struct SquareBlob {
	cv::Rect box;		// image pixels
	cv::Mat mask;		// CV_8U 0/255, box.size()
	double inside = 0;	// median intensity inside the square
	double outside = 0;	// median intensity of the gap around it
};

/// Finds the pattern's squares on the intensity plane: local-mean threshold, blob filtering,
/// then a per-square threshold at the midpoint of its own inside and gap levels. Fills centroid
/// (area centroid) and area of each Square; blobs[i] belongs to squares[i].
Status find_squares(const cv::Mat &intensity, const SquareParams &params,
		    std::vector<Square> *ret_squares, std::vector<SquareBlob> *ret_blobs);
/// The first-pass window find_squares uses on a frame of `frame` size: params.first_window_px,
/// or derived from the frame (a crop searched on its own must pass the whole frame's).
int first_window_px(const SquareParams &params, cv::Size frame);

// ---- stage 5: force-field corners + sub-pixel refinement -------------------------------------

struct CornerParams {
	bool subpixel = true;
	/// Edge samples are taken on each side between these fractions of its length.
	double side_margin = 0.12;
	int samples_per_side = 12;
	/// Half length of the intensity profile across an edge, in pixels (clamped to the gap).
	double profile_half_px = 4.0;
	/// A refined corner further than this (or 0.2 side, if more) from its pixel-level estimate
	/// is rejected.
	double max_shift_px = 3.0;
	/// Line-fit RMS above which the square's corners are rejected, pixels.
	double max_fit_rms_px = 0.8;
};

/// The paper's force-field corners of a binary square (CV_8U, non-zero inside): on the square's
/// boundary pixels, F_h / F_v = length of the horizontal / vertical boundary run through the
/// pixel, F_total = F_h + F_v; the bounding box is split in four quadrants and each quadrant's
/// corner is the F_total maximum (ties: mean position of the tied pixels). Returns corners in
/// mask pixel coordinates, image-sense order TL, TR, BR, BL. -EINVAL for an empty mask.
Status force_field_corners(const cv::Mat &mask, std::array<cv::Point2d, 4> *ret_corners);

/// Sub-pixel refinement. The initial corners split the mask's boundary into four sides (by each
/// boundary pixel's gradient direction), whose pixel-level lines give corners to within a fraction
/// of a pixel even when the force field's tie averaging left them a few pixels off. Then each
/// side's edge is located at the midpoint level between the square's
/// inside and gap intensity along profiles across it, a line is fitted per side and adjacent
/// lines are intersected. `corners` (image pixels, TL TR BR BL) are the initial estimate.
/// -ERANGE when the fit is poor or moves a corner more than max_shift_px (corners untouched).
Status refine_corners(const cv::Mat &intensity, const SquareBlob &blob, const CornerParams &params,
		      std::array<cv::Point2d, 4> *corners);

/// Runs force_field_corners (+ refine_corners) on every square; sets corners/has_corners, and
/// the centroid to the diagonals' intersection (projectively invariant, so the same surface point
/// in both cameras) where corners were found.
void detect_corners(const cv::Mat &intensity, const std::vector<SquareBlob> &blobs,
		    const CornerParams &params, std::vector<Square> *squares);

// ---- stage 1c: letters from hue, adaptive per capture ----------------------------------------

struct HueParams {
	double gamma = 2.2;		// the camera's output encoding (1 = linear)
	int iterations = 8;		// k-means iterations on the hue circle
	double min_saturation = 0.08;	// chroma / intensity below which a square has no letter
	/// Squares whose inside colour spread (circular hue std, degrees) exceeds this are mixed
	/// (projector seams) and get no letter.
	double max_hue_spread_deg = 25;
	/// Confidence below which the letter is dropped (letter = -1, kept as a decodable gap).
	double min_confidence = 0.3;
};

/// Classifies each square's letter from its inside colour: white-balanced against the capture's
/// mean square colour, then a k-means on the hue circle seeded at the pattern's letter hues.
/// Confidence = margin between the nearest and second nearest cluster (0..1).
Status classify_letters(const cv::Mat &bgr, const std::vector<SquareBlob> &blobs,
			const Pattern &pattern, const HueParams &params, std::vector<Square> *squares);

// ---- stage 1d: letter planes (superposed slide copies) ---------------------------------------

/// Two projectors of about the same pitch and roll that light the same part of the face (random
/// booths, overlapping mode) superpose two copies of the slide offset by a fraction of a cell: the
/// squares of a row run together into strips, which the intensity stage refuses, and a camera can
/// decode nothing. Light adds, and the three letter colours are independent in RGB, so each pixel
/// splits into the light of each letter: in one letter's plane the other copy's squares of other
/// letters vanish and most squares stand alone again.
struct LetterPlaneParams {
	bool enabled = true;
	/// Only a view that decodes fewer than this share of its squares from intensity alone is
	/// searched again in the planes (the default scene decodes 72-82 %).
	double max_decoded_share = 0.5;
	/// Squares of each letter (from the intensity stage) needed to measure its colour in this view.
	int min_squares_per_letter = 4;
	/// A plane keeps a pixel only where its letter's light is at least this share of the
	/// strongest letter's there (what a colour error leaks into the other planes stays out).
	double min_share = 0.3;
	/// A plane's square is the same as an intensity square when each holds the other's centre
	/// and their areas differ by less than this factor; it is then not added.
	double same_area_ratio = 1.6;
	/// A plane's square is kept when 1 − (strongest other letter's mean light in it / its own)
	/// reaches this; it is also its letter's confidence.
	double min_confidence = 0.2;
};

/// The linear colour (B, G, R, inside minus gap, unit sum) of each letter in this view: the mean
/// over the squares classify_letters gave that letter. -ENODATA when a letter has fewer than
/// `min_squares` squares, -EINVAL on bad input.
Status letter_colours(const cv::Mat &bgr, const std::vector<SquareBlob> &blobs,
		      const std::vector<Square> &squares, int letters, double gamma, int min_squares,
		      std::vector<cv::Vec3d> *ret_colours);

/// Splits the frame's linear light into one CV_32F plane per letter by inverting the 3 × 3 mixing
/// matrix of the letters' colours (exactly 3 letters; -EINVAL otherwise or when the colours are
/// not independent). A plane is 0 where its share of the light is below `min_share`.
Status letter_planes(const cv::Mat &bgr, double gamma, const std::vector<cv::Vec3d> &colours,
		     double min_share, std::vector<cv::Mat> *ret_planes);

/// Finds squares in each letter plane (find_squares, detect_corners on the plane, letter = the
/// plane's) and merges them into `squares`/`blobs`. The planes cover the image from `origin`
/// (they may be a crop). A plane square that is an intensity square already, that lies in one read
/// whole (corners and a letter), that has no corners or is below `min_confidence` is skipped; an
/// intensity square that holds a new plane square's centre was a blend of two copies and is
/// dropped. -EINVAL on bad input.
Status add_letter_squares(const std::vector<cv::Mat> &planes, cv::Point origin,
			  const SquareParams &squares_params, const CornerParams &corner_params,
			  const LetterPlaneParams &params, std::vector<Square> *squares,
			  std::vector<SquareBlob> *blobs);

// ---- stage 2: grid topology ------------------------------------------------------------------

struct GridParams {
	/// In the square's own projective frame (slide units, one pitch = 1) a neighbour's centre
	/// must lie within this angle of the direction and between these distances; the nearest wins.
	/// The range is wide because the frame of one small square extrapolates poorly on a face
	/// that curves away (measured on the simulator: 0.8-1.35 pitches).
	double max_angle_deg = 30;
	double min_pitches = 0.55, max_pitches = 1.6;
	/// Shape check (after decoding): a square's side lengths may differ from what its neighbours
	/// predict by this fraction (both neighbours known) or `single_tolerance` (one known).
	double shape_tolerance = 0.2, single_tolerance = 0.3;
};

/// Links each square to its up/left/right/down neighbour in the image's sense (decode_cells turns
/// them into the slide's sense): the square's own corners define a local homography to slide
/// units, in which the neighbour's centre must lie about one pitch away in about the right
/// direction (the nearest such square). Links are kept only when mutual. `gap_fraction` is the slide's.
void link_grid(double gap_fraction, const GridParams &params, std::vector<Square> *squares);

/// Marks squares whose shape disagrees with their neighbours' (Square::irregular; their corners
/// are dropped). A shadow edge or an occluding contour cuts a whole row of squares alike, so each
/// square's vertical sides are predicted from its up/down neighbours and its horizontal sides from
/// its left/right neighbours (slide sense, so after decode_cells).
void check_grid_shapes(const GridParams &params, std::vector<Square> *squares);

// ---- stage 3: decoding -----------------------------------------------------------------------

struct DecodeParams {
	/// Correct one wrong or missing letter when exactly one cell's word fits.
	bool correct = true;
	/// A decoded cell needs this many neighbours whose cells agree (grid consistency).
	int min_support = 1;
	/// Rounds of propagation of cell ids from decoded neighbours (border squares, gaps).
	int propagate_rounds = 3;
	/// Try the slide turned by a quarter turn in the image (projectors rolled 90°, as in the
	/// default simulated rig), per connected part of the grid.
	bool any_rotation = true;
	/// Squares a component's best rotation leaves undecoded are split off into parts; a part
	/// that decodes at least this many in its own rotation becomes a component (two projectors'
	/// copies linked across a seam, rolled differently). 0 = never split.
	int split_min_decoded = 4;
	int max_splits = 2; // per component: one per other projector
};

/// Decodes the code word (up, left, centre, right, down) of each square to its matrix cell,
/// corrects single errors, checks neighbour agreement, propagates ids to undecoded neighbours.
/// Per connected part of the grid it finds the slide's quarter-turn rotation in the image (the
/// one that decodes most squares) and rewrites neighbours and corners into the slide's sense.
/// Sets cell/corrected per square and detected/decoded/corrected/rejected of `dets`.
void decode_cells(const Pattern &pattern, const DecodeParams &params, CameraDetections *dets);

// ---- stages 1-3 + 5 for one camera -----------------------------------------------------------

struct DetectParams {
	double gamma = 2.2;	// the camera's output encoding, undone before any stage (1 = linear)
	SquareParams squares;
	CornerParams corners;
	HueParams hue;
	LetterPlaneParams planes;
	GridParams grid;
	DecodeParams decode;
};

/// One camera frame (8-bit BGR) → its squares with letters, neighbours, cells and corners.
/// ret->camera is left as the caller set it. -EINVAL for an empty or non-BGR frame.
Status detect_squares(const cv::Mat &bgr, const Pattern &pattern, const DetectParams &params,
		      CameraDetections *ret);

// ---- stage 4: correspondence ------------------------------------------------------------------
//
// match_pair = match_codes → grow_matches → (guide_matches → grow_matches) × up to GuideParams::rounds
//              → seed_matches → prune_matches.
// Each sub-stage takes the PairMatches the one before it produced and adds to them (or, prune,
// takes from them); the pair's geometry is computed once (pair_geometry) and shared.

/// The epipolar geometry of a camera pair and the undistorted features of both views' squares,
/// computed once per pair for every sub-stage of stage 4.
struct PairGeometry {
	cv::Matx33d E, R;	// essential matrix and rotation: x_b = R x_a + t (camera a's frame, mm)
	cv::Vec3d t;
	double fa = 0, fb = 0;	// mean focal lengths, px (epipolar distances are in pixels)
	/// Normalised (undistorted) image coordinates, kFeatureCount per square: its centroid, then its
	/// 4 corners (the centroid again where it has none). na for camera a, nb for camera b.
	std::vector<cv::Point2d> na, nb;
};

/// The geometry of the pair (a, b) seen by cameras ca and cb. -EINVAL when an intrinsic matrix has
/// no focal length or the two cameras share their centre.
Status pair_geometry(const CameraDetections &a, const CameraDetections &b, const CameraModel &ca,
		     const CameraModel &cb, PairGeometry *ret);

/// What every square pair matched by any sub-stage (4-4d) must satisfy.
struct PairCheckParams {
	/// Plausible depth of a matched point in camera a's frame, mm (rejects wrong slide copies).
	double min_depth_mm = 150, max_depth_mm = 1500;
	bool corners = true;		// also match the 4 corners of matched squares
	/// Every corner of a matched square must be this close to its epipolar line, or the whole
	/// square is refused (it is cut differently in the two views).
	double max_corner_epipolar_px = 1.5;
	/// Epipolar limit for squares matched without their code word (grown, guided, seeded). The
	/// grid topology (or the depth range) already names the candidate, so this only refuses gross
	/// errors; such squares are often the ones without corners (their area centroid is not
	/// projectively invariant) or half lit (mixed, dim), so it is looser than the code's.
	double max_uncoded_epipolar_px = 3.0;
};

/// Stage 4 (code): matching by cell id.
struct CodeMatchParams {
	/// A square pair is matched when its centroids are this close to their epipolar lines
	/// (symmetric distance, pixels), or when all four corners are within the check's
	/// max_corner_epipolar_px: a corner is the image of one surface point, the area centroid of
	/// a square seen obliquely is not, and on a pair converging by ~45 degrees a right match's
	/// centroid lies 2-6 px off while its corners lie within 0.5 px.
	double max_epipolar_px = 2.0;
	/// Two connected parts of the decoded grids (one in each camera) show the same copy of the
	/// slide when at least this fraction of their shared cells, and this many (or all when
	/// fewer), pass the depth check and lie within copy_epipolar_px (or pass on their corners).
	/// The vote tells copies apart, which lie on different parts of the face, tens of pixels off
	/// each other's epipolar lines; at max_epipolar_px it also refused the right copy where the
	/// centroids of oblique squares drift (random booths 3800 pair 0-1, 10 of 17 cells within
	/// 2 px, 14 within 4; 3803 pair 1-2, 6 and 10 of 11: no code match in either pair).
	double copy_epipolar_px = 4.0;
	double min_part_agreement = 0.6;
	int min_part_support = 3;
};

/// Matches the squares of two cameras by cell id (centroid + corners, the same feature of the same
/// square), keeping a pair only when it satisfies the epipolar constraint and a plausible depth,
/// and when the connected grid parts the two squares belong to agree as a whole (the same copy of
/// the slide: all three projectors throw it, so a cell id can appear up to three times in each
/// camera). A square with several such candidates is rejected (rejected_ambiguous), one with none
/// counts in rejected_epipolar; one square never takes two partners. Irregular squares are not
/// matched by their code. Sets *ret anew (cam_a, cam_b from the detections). -EINVAL when `g` is
/// not the geometry of these detections.
Status match_codes(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		   const Pattern &pattern, const PairCheckParams &check, const CodeMatchParams &params,
		   PairMatches *ret);

// Stages 4b-4d match the squares the code did not match. The code only serves to find where a
// square is in the other view; a square whose code word could not be read (a missing neighbour, a
// dim or mixed colour in a projector seam, a slide border cell) or whose grid links are broken
// (around a nostril, a lip, an eyelid) is still the same surface patch in both views, and can be
// found from the squares already matched around it. Every way the pair must pass the same tests:
// letters and cells do not contradict, the epipolar line (max_uncoded_epipolar_px) and a plausible
// depth; its corners as in match_codes. Once all are matched, prune_matches drops those that lie
// off the surface their neighbours describe. Each takes `matches` as the sub-stage before left
// them and adds to them; -EINVAL when `g` or `matches` do not belong to these detections. A
// sub-stage whose Params are not `enabled` does nothing.

/// Stage 4b: growing along both grids.
struct GrowParams {
	bool enabled = true;	// false: grow_matches adds nothing (seed_matches still grows its seeds)
};

/// Once a square is matched, its grid neighbour in direction d in camera a and the neighbour in
/// direction d of its partner in camera b are the same projected square — whether or not its code
/// word was read — when every neighbour already matched agrees (topology). Grows from every
/// matched square, depth first, until nothing is added; adds to matches->grown. match_pair grows
/// after match_codes and after each round of guide_matches.
Status grow_matches(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		    const PairCheckParams &check, const GrowParams &params, PairMatches *matches);

/// Stage 4c: guided matching along the epipolar line.
struct GuideParams {
	bool enabled = true;
	/// match_pair runs up to this many rounds (until one finds nothing), each followed by growing.
	int rounds = 4;
	/// Depth range from the matched squares of camera a within this many grid pitches (at least
	/// this many of them), widened by this margin.
	double radius_pitches = 2.5;
	int min_around = 3;
	double depth_margin_mm = 8;
};

/// One round: for a square still unmatched in camera a, the matched squares around it bound its
/// depth, and along its epipolar line in camera b exactly one unmatched, compatible square may lie
/// in that range (and it must not be the only candidate of another square of a). Adds to
/// matches->guided.
Status guide_matches(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		     const PairCheckParams &check, const GuideParams &params, PairMatches *matches);

/// Stage 4d: seeded growth into parts no code word or matched neighbour reaches.
struct SeedParams {
	bool enabled = true;
	/// The seed's trial growth must pair this many squares whose letters agree, twice as many as
	/// any other candidate's, at a depth within the pair's matched range widened by the margin.
	int min_support = 5;
	double depth_margin_mm = 20;
};

/// Seeds growth in parts of the grid that neither a code word nor a matched neighbour reaches
/// (a band of neck under the chin, two rows tall, where no word is complete): a candidate pair
/// of squares is tried by growing from it along both grids without committing; the letters it
/// would pair must agree on every square where both are known, and only a seed whose growth
/// pairs at least `min_support` such squares, far more than any other candidate for the same
/// square, is kept (a wrong candidate on the epipolar line pairs letters at random, one in
/// three). Depth stays within the range of the pair's matched squares, widened by
/// `depth_margin_mm`. Each seed is grown from at once, whatever GrowParams say (a seed is only
/// as good as its growth): adds to matches->seeded and matches->grown. Nothing is seeded when no
/// square is matched yet.
Status seed_matches(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		    const PairCheckParams &check, const SeedParams &params, PairMatches *matches);

/// Stage 4e: pruning matches off their neighbours' surface.
struct PruneParams {
	/// A grown, guided or centroid-only square's centroid must lie within this distance of the
	/// quadric fitted to its `surface_points` nearest matched points of other squares within
	/// `surface_radius_mm` (at least half of them must be that near; below 6, a plane is fitted).
	double max_surface_residual_mm = 2.5;
	/// The same for a square cut or merged in one view: corners in one view only, and its area
	/// in the two views out of the proportion its matched grid neighbours show (outside this
	/// range). The two centroids need not be one surface point: on simulated heads the matches
	/// with the largest errors (up to 4 mm) were of this kind.
	double max_one_sided_residual_mm = 1.5;
	std::array<double, 2> one_sided_area_proportion{{0.7, 1.5}};
	/// An irregular square whose centroid is farther than this (about a grid pitch on the face)
	/// from every matched point of other squares is dropped: it was grown or guided across an
	/// occluding contour (chin over neck), where its neighbours' surface only extrapolates.
	double max_irregular_isolation_mm = 10;
	int surface_points = 10;
	double surface_radius_mm = 20;
};

/// Removes the grown and guided squares, and the squares matched by their centroid alone (no
/// corner to check them by), whose centroid lies off the surface the other matched points describe
/// around it: a wrong candidate along the epipolar line, or a centroid shifted by a cut in one
/// view. Run after all matching, so the neighbourhood surrounds the square. Twice: a bad square
/// bends its neighbours' fits. Adds the squares it removed to matches->pruned.
Status prune_matches(const CameraDetections &a, const CameraDetections &b, const PairGeometry &g,
		     const PruneParams &params, PairMatches *matches);

/// Stage 4 as the pipeline runs it: the sub-stages' Params.
struct MatchParams {
	PairCheckParams check;
	CodeMatchParams code;
	GrowParams grow;
	GuideParams guide;
	SeedParams seed;
	PruneParams prune;
};

/// match_codes, then the squares the code did not match are grown along both grids, guided along
/// their epipolar lines and, where nothing reaches, seeded by trial growth; every match not
/// checked by its corners is pruned when it lies off its neighbours' surface (counts in grown,
/// guided, seeded, pruned). -EINVAL as pair_geometry.
Status match_pair(const CameraDetections &a, const CameraDetections &b, const CameraModel &ca,
		  const CameraModel &cb, const Pattern &pattern, const MatchParams &params,
		  PairMatches *ret);

} // namespace facescan::recon
