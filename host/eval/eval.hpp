// Accuracy of a reconstruction against a ground-truth mesh (the simulator's ground_truth.ply):
// vertex-to-surface distances and completeness. Used by the benchmark (`make bench`, via
// `facescan evaluate`) and by the end-to-end test, which asserts bounds on a small scene.
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "recon/types.hpp"

#include <memory>
#include <string>
#include <vector>

namespace facescan::eval {

/// Distance from points to a triangle mesh, with a uniform grid over the triangles.
class MeshDistance {
public:
	/// `cell_mm`: grid cell side (about the mesh's edge length is right).
	MeshDistance(const std::vector<cv::Point3f> &positions, const std::vector<cv::Vec3i> &triangles,
		     double cell_mm);
	~MeshDistance();
	MeshDistance(const MeshDistance &) = delete;
	MeshDistance &operator=(const MeshDistance &) = delete;
	/// Unsigned distance to the nearest triangle, searched out to `max_mm`; +inf beyond it.
	double distance(const cv::Point3d &p, double max_mm) const;

private:
	struct Impl;
	std::unique_ptr<Impl> impl_;
};

/// Distance from p to triangle (a, b, c) (Ericson, Real-Time Collision Detection, 5.1.5).
double point_triangle_distance(const cv::Point3d &p, const cv::Point3d &a, const cv::Point3d &b,
			       const cv::Point3d &c);

struct EvalParams {
	double completeness_mm = 1.0;	// a truth point counts as covered within this distance
	int min_cameras = 2;		// truth points seen by fewer cameras are not counted
	double min_cos = 0.1;		// a camera (or projector) must face the surface this much
	double depth_scale = 0.5;	// z-buffer resolution for visibility, relative to the device
	double occlusion_tolerance_mm = 1.0;
	double max_search_mm = 20;	// distances beyond this count as this (outliers)
	/// Per projector (same order as `projectors`), the polygon of its slide that throws light,
	/// in slide pixels; a point lights only where it projects inside. Empty (or an empty
	/// polygon) = the whole slide. read_ground_truth() reads them from a simulated set.
	std::vector<std::vector<cv::Point2d>> projector_masks;
	/// Per truth vertex, 1 on the face (hairline to chin, ear to ear: the "face"), for
	/// the face figures of EvalResult; empty = none (a set without ground_truth_face.ply).
	/// read_ground_truth() reads it from a simulated set.
	std::vector<char> truth_face;
};

struct EvalResult {
	// Reconstruction vertex → truth, each distinct position once (a vertex the texture atlas
	// duplicated on a chart seam counts once).
	double rms_mm = 0, median_mm = 0, p95_mm = 0, max_mm = 0;
	int unique_positions = 0;	// distinct vertex positions the figures above are over
	/// Per reconstruction vertex: its distance to the truth, mm (capped at max_search_mm).
	std::vector<float> vertex_mm;
	double completeness = 0;	// fraction of counted truth points within completeness_mm
	int truth_points = 0;		// truth vertices
	int truth_counted = 0;		// ... seen by >= min_cameras cameras (and lit, see below)
	int vertices = 0, triangles = 0;
	int face_vertices = 0;		// distinct vertex positions within ~2 mm of a counted truth point
	/// Per truth vertex: -1 not counted (seen by too few cameras or unlit), 0 missed, 1 covered.
	std::vector<signed char> truth_status;
	// The same figures over the face's truth vertices only (EvalParams::truth_face; all 0 without
	// it): what the "completeness >= 85 %" and ">= 100k vertices on the face" are over.
	int face_truth_points = 0;	// face truth vertices (0: no face given, no face figures)
	int face_counted = 0;		// ... seen by >= min_cameras cameras and lit, as truth_counted
	double face_completeness = 0;	// fraction of the counted face points within completeness_mm
	int face_region_vertices = 0;	// distinct positions within ~2 mm of a face truth point
};

/// A simulated capture set's ground truth: CAPTURE_DIR/ground_truth.ply (the head, world mm) and,
/// when the set records them, the projectors that lit it (ground_truth_projectors.yaml; left
/// empty for older sets). `ret_masks`, if given, gets each projector's slide mask (the file's
/// `cam{j}_slide_mask: [x0, y0, x1, y1, ...]`; an empty polygon where it has none): pass them
/// as EvalParams::projector_masks. `ret_face`, if given, gets per truth vertex 1 where it is a
/// vertex of ground_truth_face.ply (the face region, the same float positions as
/// ground_truth.ply's), left empty when the set has no such file (older sets): pass it as
/// EvalParams::truth_face. -ENOENT when the set has no ground truth, -EINVAL for a malformed
/// mask or face file (not a PLY, no vertices, or a vertex ground_truth.ply does not have), and
/// the mesh readers' errors (a FIFO or device is refused, -EFBIG beyond their size cap).
Status read_ground_truth(const std::string &capture_dir, recon::Mesh *ret_truth,
			 std::vector<CameraModel> *ret_projectors,
			 std::vector<std::vector<cv::Point2d>> *ret_masks = nullptr,
			 std::vector<char> *ret_face = nullptr);

/// Per vertex of `truth`: 1 where `face`'s vertices (a subset of truth's, by exact position) put
/// one. -EINVAL when `face` has no vertices or one that `truth` does not have.
Status match_face_vertices(const recon::Mesh &truth, const recon::Mesh &face, std::vector<char> *ret_face);

/// Per vertex of `mesh` (world mm; `normals` per vertex): 1 when `device` sees it unoccluded
/// (params.depth_scale, params.occlusion_tolerance_mm) and faces it at least params.min_cos —
/// and, when `slide_mask` is not empty, the point projects inside that polygon (a projector's
/// slide mask; projectors are pinholes). The test behind evaluate()'s "seen" and "lit".
std::vector<char> seen_by(const CameraModel &device, const recon::Mesh &mesh, const std::vector<cv::Point3f> &normals,
			  const EvalParams &params, const std::vector<cv::Point2d> &slide_mask = {});

/// Compares `recon` with `truth` (both world mm). Truth points are the truth mesh's vertices
/// that at least `min_cameras` cameras see unoccluded and front-facing — and, when
/// `projectors` is not empty, that at least one projector lights (the pattern can only be
/// measured where it falls): faces it, is not shadowed and, where params.projector_masks gives
/// the projector a mask, projects inside it. With params.truth_face the face figures are the
/// same over the face's truth vertices. -EINVAL for an empty mesh, more masks than projectors,
/// or a truth_face that is not one entry per truth vertex.
Status evaluate(const recon::Mesh &recon, const recon::Mesh &truth, const std::vector<CameraModel> &cameras,
		const std::vector<CameraModel> &projectors, const EvalParams &params, EvalResult *ret_result);

/// One pair's dense stage as `facescan recon --debug DIR` left it: its cameras, the projection of
/// a world point into its rectified left view, per rectified pixel the recon::DenseReason, and
/// its cloud as the surface got it.
struct PairTrace {
	int cam_a = -1, cam_b = -1;
	cv::Matx34d world_to_left;
	cv::Mat reason; // CV_8U
	std::vector<cv::Point3f> cloud;
};

/// Reads DIR/pair{p}_rectification.yaml, pair{p}_reasons.png and pair{p}_dense.ply for p = 0, 1,
/// ... while they exist (a pair whose dense stage failed has none and ends the list). -ENOENT
/// when DIR has no pair's.
Status read_pair_traces(const std::string &debug_dir, std::vector<PairTrace> *ret_traces);

/// Where a missed truth point went, the furthest any pair seeing it got: values 1-11 are the
/// recon::DenseReason the pair's pixel got; and these.
enum MissReason : signed char {
	kMissNoPair = 0,	 // no pair's two cameras both see it (seen by two cameras of no pair)
	kMissOff = 12,		 // a pair kept the pixel, its cloud has no point within completeness_mm
	kMissFused = 13,	 // a pair's cloud has a point within completeness_mm: the surface lost it
	kMissReasons = 14,
};

/// Short name of a MissReason (for tables and legends).
const char *miss_reason_name(int reason);

/// Per truth vertex: -1 when `result` did not count it missed, else its MissReason over the pairs
/// in `traces` whose two cameras see it (seen_by with `params`). The pixel a point falls on is
/// its nearest in the pair's rectified left view.
std::vector<signed char> attribute_missing(const recon::Mesh &truth, const EvalResult &result,
					   const std::vector<CameraModel> &cameras,
					   const std::vector<PairTrace> &traces, const EvalParams &params);

} // namespace facescan::eval
