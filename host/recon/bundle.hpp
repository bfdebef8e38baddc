// Stage 6a: the calibration's extrinsics refined on the code's own correspondences.
//
// A good calibration leaves each camera a few tenths of a pixel off (bench: ~0.3 px), which moves
// each pair's triangulated sheet by a few tenths of a millimetre — as much as all the matching
// error on some booths. Every scan measures the booth again: the code's matched corners are
// exact projective features seen by two or three cameras. Bundle adjustment over them, with the
// calibration as a prior, puts the cameras where their images agree. The code's tracks are mostly
// seen by two cameras; after the dense stage, the pairs' clouds chained through their shared
// cameras add three-view tracks, which tie each pair's depth to its neighbours' (stage 6b).
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "recon/dense.hpp"
#include "recon/types.hpp"

#include <vector>

namespace facescan::recon {

struct BundleParams {
	bool enabled = true;
	/// How far the calibration may be off, one sigma: each camera's rotation (rad, per axis)
	/// and centre (mm, per axis) — a good calibration's (~0.3 px reprojection: ~0.05 mrad,
	/// ~0.05 mm). The refinement's prior: the images leave some motions of the cameras nearly
	/// free (a pair's depth scale against its convergence), and looser priors let the solution
	/// wander along them (12 bench scenes: 3e-4 rad / 0.2 mm was worse than 5e-5 / 0.05 on every
	/// one, 1e-3 / 0.5 worse than no refinement). A booth whose calibration is known to be worse
	/// should say so here.
	double sigma_rotation_rad = 5e-5;
	double sigma_centre_mm = 0.05;
	/// The matched corners' precision, pixels, and the residual beyond which an observation is
	/// down-weighted (Huber): a wrong match must not drag the booth.
	double sigma_px = 0.2;
	double huber_px = 0.6;
	int reweight_rounds = 2;
	int max_iterations = 50;
	/// Fewer tracks than this: the calibration stands as written.
	int min_tracks = 30;
	/// Second pass (after the dense stage): the dense clouds of pairs (p, p+1) and (p+1, p+2)
	/// chained through camera p+1 give three-view tracks, one per `chain_cell_px` square of that
	/// camera's image (0: no second pass), from the first cloud's most confident point there. A
	/// track is kept where the second cloud is a plane within `chain_fit_mm` (RMS) over 8 px
	/// around the point and the two clouds agree within `chain_gap_mm` along the shared camera's
	/// ray (a calibration error parts them by tenths of a millimetre, a mismatch by more).
	/// Fewer than `chain_min_tracks` tracks through one camera: none of them is used (held-out
	/// 3101-scan: one track through camera 1 moved it 0.07 mm, RMS 0.321 -> 0.375 mm).
	int chain_cell_px = 16;
	int chain_min_tracks = 30;
	double chain_gap_mm = 2.0;
	double chain_fit_mm = 0.3;
};

struct BundleCamera {
	int camera = -1;
	double rotation_mrad = 0; // how far the refinement turned it
	double centre_mm = 0;	  // how far it moved its centre
};

struct BundleStats {
	bool applied = false;
	int tracks = 0;		  // distinct surface points (a square's corner)
	int tracks_3_views = 0;	  // ... seen by three cameras or more (two pairs)
	int extra_tracks = 0;	  // ... given beside the code's (the dense clouds chained)
	int observations = 0;
	double rms_before_px = 0; // reprojection of the tracks' best points, before and after
	double rms_after_px = 0;
	std::vector<BundleCamera> cameras;
};

/// Refines the rotations and centres of `cameras` (intrinsics fixed) on the tracks the pairs'
/// code matches of square corners form (centroids are not used: the centroid of a square's image
/// is not the image of one surface point): pair p's match and pair p+1's that share a corner of
/// one square in camera p+1 are one surface point. `extra_tracks` (stage 6b's chained tracks;
/// empty in stage 6a) are added as they are; one naming a camera outside `cameras` is skipped.
/// Minimises the tracks' reprojection error (robust) plus the calibration prior. With fewer
/// than `min_tracks` tracks, or when disabled, `cameras` is left untouched and stats->applied is
/// false. -EINVAL when a match names a camera outside `cameras`.
Status refine_extrinsics(const std::vector<PairMatches> &pairs, const std::vector<Track> &extra_tracks,
			 const BundleParams &params, std::vector<CameraModel> *cameras, BundleStats *stats);

/// Three-view tracks from the dense clouds of consecutive pairs (BundleParams::chain_*): a point
/// of pair (p, p+1)'s cloud, its pixel in camera p+1, and pair (p+1, p+2)'s surface along that
/// pixel's ray, seen in camera p+2. `cameras` are those the clouds were triangulated with.
void chain_dense_tracks(const std::vector<DenseCloud> &clouds, const std::vector<CameraModel> &cameras,
			const BundleParams &params, std::vector<Track> *tracks);

/// Each cloud point re-triangulated with the cameras `after` from its pixels under `before` (the
/// cameras it was triangulated with; same intrinsics).
void retriangulate_clouds(const std::vector<CameraModel> &before, const std::vector<CameraModel> &after,
			  std::vector<DenseCloud> *clouds);

} // namespace facescan::recon
