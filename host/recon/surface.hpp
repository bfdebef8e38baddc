// Stage 9 (dense): the pairs' registered dense clouds fused into one surface over the view
// sphere (fusion.hpp's ViewFrame). Every point is splatted bilinearly onto a grid of directions
// from the sphere's centre with the paper's distance-to-border weight (times its confidence);
// per cell the samples that agree with its strongest one (another sheet or an outlier does not)
// are averaged into one radius. One radius per direction means one sheet where the pairs
// overlap, and the grid's own triangles join the pairs without a crack.
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "recon/dense.hpp"
#include "recon/types.hpp"

#include <vector>

namespace facescan::recon {

struct SurfaceParams {
	/// Grid step on the sphere, at the surface's median radius: about one camera pixel on the
	/// face (0.25-0.4 mm on the random booths), now that the dense stage gives a point per pixel
	/// the refinement measured (DenseParams::points_at_refine_scale; 0.45 before 2026-12-06,
	/// with a point per matching pixel). Bench booths 101-112 (head 0): 2.7x the input points,
	/// 1.6x the vertices (each still backed by ~1.8 points), RMS lower on 10 of 12.
	double spacing_mm = 0.35;
	double agree_mm = 1.2;	      // samples farther than this from a cell's strongest are not averaged
	double border_floor_mm = 0.5; // weight = min(border distance, cap) + floor
	double border_cap_mm = 15;
	/// A grid triangle is kept when its 3-D edges are at most this many grid steps long: steeper
	/// than ~80 degrees against the sphere is a depth jump, not a surface.
	double max_edge_steps = 6;
	int smooth_passes = 1;	      // 3x3 averaging of agreeing neighbours' radii
	/// After the outlier test, each radius is put on the plane fitted to the agreeing radii within
	/// this distance (a square window, weighted like the fusion; 3 cells at 0.35 mm). 2026-12-07,
	/// 24 fresh booths (4100-4111, both heads): RMS lower on 24 of 24, mean -0.018 mm, face
	/// completeness within -0.1/+0.1 points; not tuned on (4200-4211): 24 of 24, -0.017 mm.
	/// 2.45 mm (7 cells) gave -0.027 mm but rounds the tightest curves (nose, lips: truth
	/// curvature > 0.2/mm) by up to +0.05 mm RMS where 1 mm lowers them. 0: off.
	double plane_fit_mm = 1.0;
	double min_weight = 0.05;     // cells with less total weight are empty (> 0)
	long max_cells = 6000000;     // bigger grids take a coarser step (bounds memory)
	int median_radius = 3;	      // cells: the neighbourhood of the outlier test (0: none)
	double max_median_dev_mm = 1.0; // farther from the neighbourhood's median radius: an outlier
	double min_piece_fraction = 0.02; // connected pieces smaller than this * the largest are dropped
	/// ... unless at least this fraction of their vertices were averaged from two or more pairs
	/// (0: off). Where the surface falls apart into pieces (bench booth 111: mouth, chin and a
	/// cheek 2-6k triangles each, under 2 % of the largest), the ones a second pair confirms stay:
	/// 111-head1110 face completeness 76.9 -> 80.1 %, 111-head1112 79.5 -> 83.1, RMS -0.001 mm
	/// (106-head1060 and 1061: +1.3 and +0.3 points, +0.018 and +0.019 mm, a kept piece 13 % of
	/// whose vertices are > 1 mm off). Of what the size rule drops on the bench's 48 scenes
	/// (2026-12-07), this keeps 7 % of the vertices and 0.2 % of the badly placed ones (pieces
	/// whose median is > 1 mm off). Fresh booths 6400-6411 and 7200-7211 (48 scenes): 45
	/// unchanged, 6404 +1.3 points / +0.004 mm, RMS at most +0.007 mm.
	double piece_two_pair_fraction = 0.2;
	/// ... or, within `piece_code_reach_mm` of the code's own points (the paper's sparse mesh,
	/// from decoded squares, not from the dense search) that lie within `piece_code_mm` of a
	/// vertex of theirs, when at least `piece_code_points` do (0: off). A wrong piece comes from
	/// a search that strayed where the code said nothing; a right one is often cut off by a band
	/// no projector lights, with the code read on it. 2026-12-08, the pieces the two rules above
	/// drop on 10 scenes (bench 111 x 3, 107, held-out 8007, 8008, fresh 8800, 8801, 8802, 8809):
	/// 25 of them > 1 mm off (median to the truth), none with a code point within 2 mm; 272 right,
	/// 20 of them (51k triangles) with two code points within 1 mm. Whole pieces were kept at
	/// first: bench 111-head1112 then kept two whose median is right but whose tail is not (p90
	/// 1.8-1.9 mm), RMS 0.226 -> 0.272; near the code points only, 0.228.
	int piece_code_points = 2;
	double piece_code_mm = 1.0;
	double piece_code_reach_mm = 5.0;
	/// The surface's outline is trimmed by this many cells: a cell there is fed only by points at
	/// their pairs' matched borders (1-2 mm off 5-8 times as often as inside: bench booth 103,
	/// 111, fresh booth 3104), and the pairs' own rim (DenseParams::rim_px) is kept one pixel
	/// narrower so that the border is trimmed once, here, where the pairs' overlaps have already
	/// filled each other's rims. Holes of at most `pinhole_cells` cells (a cell no point fell in,
	/// an outlier the median test dropped) are not outline and are not widened. 0: off.
	int trim_border_cells = 1;
	int pinhole_cells = 30;
};

struct SurfaceStats {
	int input_points = 0;
	int cells = 0;	     // grid cells with a radius
	int merged = 0;	     // cells averaged from two or more pairs
	int outliers = 0;    // cells dropped by the median test
	int trimmed = 0;     // cells dropped on the surface's outline (trim_border_cells)
	int piece_triangles_dropped = 0; // triangles of pieces split off the main surface
	int piece_triangles_two_pairs = 0; // ... of small pieces kept as two pairs agree on them
	int piece_triangles_code = 0;      // ... of small pieces kept as the code's points lie on them
	int vertices = 0, triangles = 0;
	double spacing_mm = 0;
};

/// Fuses `clouds` (world mm, registered) into `ret_mesh` (positions, triangles, normals).
/// `code_points` (world mm; may be empty) are the paper's sparse mesh's vertices, which vouch for
/// small pieces (SurfaceParams::piece_code_points). -ENODATA when nothing is left to mesh.
Status fuse_dense(const std::vector<DenseCloud> &clouds, const std::vector<cv::Point3f> &code_points,
		  const std::vector<CameraModel> &cameras, const SurfaceParams &params, Mesh *ret_mesh,
		  SurfaceStats *ret_stats);

} // namespace facescan::recon
