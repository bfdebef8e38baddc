// Stage 8: registration of the partial models (seed paper §4). Consecutive pairs share a
// camera: pair (0,1) and pair (1,2) both see camera 1, so a point whose match used camera-1
// square s, feature f in one model and the same square and feature in the other is the same
// physical grid point. Each model is moved onto the reference model (the middle pair by
// default) by the rigid R, T minimising the paper's D = 1/n Σ ||p_i − (R q_i + T)||²
// (Umeyama / SVD), after trimming correspondences far off the first fit.
#pragma once

#include "common/status.hpp"
#include "recon/types.hpp"

#include <vector>

namespace facescan::recon {

struct RegistrationParams {
	int reference = -1;	    // index of the model that stays fixed; -1 = the middle one
	int min_points = 6;	    // fewer shared points: the model stays where triangulation put it
	double outlier_factor = 3.0; // refit without pairs farther than factor * median residual
	double outlier_floor_mm = 0.5; // ... but never trim pairs closer than this
	// Apply the fit only when it lowers D by at least this fraction: with an exact calibration
	// a 6-parameter fit to noisy points only chases the noise (it lowers D by ~2/n) and would
	// tilt the far side of the model.
	double min_improvement = 0.1;
	// The dense check (check_registration_dense): a code fit is kept only when it brings the
	// pair's dense cloud closer to its neighbour's by at least this fraction of their overlap
	// distance. A handful of code points (often 20-30 at a side pair) can pass the test above
	// with a fit that moves tens of thousands of dense points off the surface.
	double dense_min_improvement = 0.05;
	double dense_cap_mm = 2.0;   // a point's distance to the other cloud counts up to this...
	double dense_reach_mm = 4.0; // ... over the points within this of it before or after the move
	int dense_stride = 8;	     // every n-th point of the moving cloud is tested
};

struct RegistrationPair {
	int model = -1, onto = -1;   // model index moved onto model `onto`
	int shared = 0, inliers = 0; // correspondences, and those kept for the final fit
	double d_before = 0, d_after = 0; // the paper's D over the inliers, mm²
	double d_before_all = 0, d_after_all = 0; // over all correspondences, mm²
	cv::Matx33d R = cv::Matx33d::eye();
	cv::Vec3d T = {0, 0, 0};
	bool applied = false;	     // false: too few shared points or no real improvement
	// The dense check: the overlap distance (mm) of the pair's dense cloud to its neighbour's
	// without and with the fit (0 when not checked), and whether the dense clouds keep the fit.
	double dense_before_mm = 0, dense_after_mm = 0;
	bool applied_dense = false;
};

/// Correspondences between two models sharing a camera: indices (i in a, j in b) of points
/// that are the same square and feature seen in the common camera.
std::vector<std::pair<int, int>> shared_points(const PartialModel &a, const PartialModel &b);

/// Least-squares rigid motion with p ≈ R q + T. -EINVAL with fewer than 3 points or a
/// degenerate (collinear) set.
Status rigid_fit(const std::vector<cv::Point3d> &q, const std::vector<cv::Point3d> &p, cv::Matx33d *ret_R,
		 cv::Vec3d *ret_T);

/// Registers the chain of models in place (points transformed). One RegistrationPair per
/// non-reference model.
Status register_models(std::vector<PartialModel> *models, const RegistrationParams &params,
		       std::vector<RegistrationPair> *ret_pairs);

/// The overlap distance of two dense clouds (mm): the mean distance from every `stride`-th point
/// of `moving`, moved by R, T, to its nearest point of `fixed`, each capped at `cap_mm`, over the
/// points that lie within `reach_mm` of `fixed` before or after the move (the overlap either
/// way). `before` receives the same measure without the move; points farther than 1 km from the
/// origin, or not finite, are left out. -ENODATA when nothing overlaps, -EINVAL when `reach_mm`
/// is not positive.
Status overlap_distance(const std::vector<cv::Point3f> &moving, const std::vector<cv::Point3f> &fixed,
			const cv::Matx33d &R, const cv::Vec3d &T, const RegistrationParams &params,
			double *ret_before_mm, double *ret_after_mm);

/// Checks the applied code fits against the dense clouds (one per model, in the models' frames
/// before registration) and moves the clouds: in the registration's order, each cloud is moved
/// by its fit only when that lowers its overlap distance to its (already moved) neighbour by
/// `dense_min_improvement`. Fills the pairs' dense_* fields.
Status register_dense(std::vector<std::vector<cv::Point3f>> *clouds, const RegistrationParams &params,
		      std::vector<RegistrationPair> *pairs);

} // namespace facescan::recon
