// Stage 7: Delaunay meshing of a point set given a 2-D parametrisation (a camera image for a
// partial model, a view sphere for the fused model), then removal of the triangles that would
// bridge a depth jump or a hole: too long an edge in 3-D (relative to the median Delaunay edge)
// or a surface seen too obliquely by every camera (a depth jump seen from the side).
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "recon/types.hpp"

#include <vector>

namespace facescan::recon {

struct MeshingParams {
	double max_edge_factor = 4.5;  // drop a triangle with an edge > factor * median edge (3-D)
	double max_grazing_deg = 78;   // drop it when every camera sees it more obliquely than this
};

struct MeshingStats {
	int delaunay = 0, kept = 0, dropped_long = 0, dropped_grazing = 0;
	double median_edge_mm = 0;
};

/// Delaunay triangulation of 2-D sites (cv::Subdiv2D). Triangles index `sites`; duplicate sites
/// collapse onto the first. Counter-clockwise in the 2-D frame.
std::vector<cv::Vec3i> delaunay_2d(const std::vector<cv::Point2d> &sites);

/// Keeps the triangles of `tris` that pass the params' edge and grazing tests over `points`,
/// each oriented so that its normal faces `towards` (a point: camera centre or outside point,
/// given per triangle through `outward`: normal · (centroid - inside) > 0).
std::vector<cv::Vec3i> filter_triangles(const std::vector<cv::Point3d> &points,
					const std::vector<cv::Vec3i> &tris,
					const std::vector<cv::Vec3d> &camera_centres,
					const cv::Point3d &inside, const MeshingParams &params,
					MeshingStats *ret_stats);

/// Meshes a partial model in the image of its first camera (distorted pixels of each source);
/// fills model->triangles.
Status mesh_partial(const CameraModel &cam_a, const CameraModel &cam_b, const MeshingParams &params,
		    PartialModel *model, MeshingStats *ret_stats);

} // namespace facescan::recon
