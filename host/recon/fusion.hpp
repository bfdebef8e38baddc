// Stage 9: fusion of the registered partial models into one mesh (seed paper §4).
// The same grid point seen by several models (linked through the square and feature of a
// shared camera) becomes one vertex at the weighted mean of its copies. Each copy's weight is
// its distance to its own model's border (plus a small floor): the blending the paper calls
// inverse-distance weighting, which fades a model out towards its edge so that no step is left
// where one model ends. The fused points are then meshed once over a view sphere around the
// head, so overlaps give one sheet, not two, and the seams between models have no cracks.
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "recon/meshing.hpp"
#include "recon/types.hpp"

#include <vector>

namespace facescan::recon {

struct FusionParams {
	double border_floor_mm = 0.5; // weight = distance to border + floor
	MeshingParams meshing;	      // edge and grazing tests of the fused mesh
};

struct FusionStats {
	int input_points = 0;	// over all models
	int vertices = 0;	// fused mesh vertices (unreferenced ones dropped)
	int merged = 0;		// vertices averaged from two or more models
	int squares = 0;	// distinct projected squares (fused centroid points) on the face
	int triangles = 0;
	MeshingStats meshing;
};

/// Distance (mm, along the mesh edges) from each point of `model` to its mesh border: 0 on a
/// boundary edge and for points in no triangle.
std::vector<double> border_distances(const PartialModel &model);

/// Weighted mean of copies of a point; the weights as above. Exposed for tests.
cv::Point3d blend(const std::vector<cv::Point3d> &copies, const std::vector<double> &border_mm,
		  double floor_mm);

/// The view sphere both fusions mesh over: its centre behind the face (from the points' centroid,
/// away from the cameras by the points' extent) and axes from the cameras' mean view and up.
struct ViewFrame {
	cv::Point3d centre;
	cv::Vec3d right, up, towards;
	double extent = 1; // the points' largest distance from their centroid, mm
};
ViewFrame view_frame(const std::vector<cv::Point3d> &points, const std::vector<CameraModel> &cameras);

/// Fuses registered models into `ret_mesh` (positions, triangles, normals). `cameras` are the
/// calibration's cameras (for the grazing test and the orientation of the sheet).
Status fuse_models(const std::vector<PartialModel> &models, const std::vector<CameraModel> &cameras,
		   const FusionParams &params, Mesh *ret_mesh, FusionStats *ret_stats);

/// Area-weighted per-vertex normals.
std::vector<cv::Point3f> vertex_normals(const std::vector<cv::Point3f> &positions,
					const std::vector<cv::Vec3i> &triangles);

} // namespace facescan::recon
