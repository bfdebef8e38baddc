// Stage 6: triangulation of one camera pair's matches into a partial model (world mm).
// Points are undistorted through each camera's calibration, triangulated linearly, refined by
// Gauss-Newton on the reprojection error, and dropped when that error stays large.
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "recon/types.hpp"

namespace facescan::recon {

struct TriangulateParams {
	double max_reprojection_px = 1.5; // mean over both views, in distorted pixels
	double min_depth_mm = 10;	  // in front of both cameras by at least this much
	int refine_iterations = 3;	  // Gauss-Newton steps after the linear solution
};

struct TriangulateStats {
	int input = 0, kept = 0, dropped_reprojection = 0, dropped_depth = 0;
	double mean_reprojection_px = 0; // over the kept points
};

/// Triangulates `pair` seen through cameras `cam_a` and `cam_b` into `ret_model` (points,
/// sources, reprojection_px; no triangles yet). -EINVAL when a camera has no valid K.
Status triangulate_pair(const PairMatches &pair, const CameraModel &cam_a, const CameraModel &cam_b,
			const TriangulateParams &params, PartialModel *ret_model, TriangulateStats *ret_stats);

/// The point halfway between the two cameras' optical axes where they pass closest: where a
/// booth's pair looks (world mm). Parallel axes: 500 mm in front of camera a.
cv::Vec3d axes_meet(const CameraModel &a, const CameraModel &b);

/// Projects world points into a camera with its distortion (pixels).
std::vector<cv::Point2d> project_points(const CameraModel &cam, const std::vector<cv::Point3d> &points);

} // namespace facescan::recon
