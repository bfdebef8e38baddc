// The reconstruction pipeline: capture set → textured face mesh, and a report of what each
// stage did and how long it took. Runs the stages in order, times them, does no file I/O
// (the CLI `facescan recon` and the daemon read and write at the edges).
//
//   detect (per camera, stages 1-3, 5) → match (per pair, 4) → triangulate (6) → mesh (7)
//   → register (8) → fuse (9) → texture (10)
// and, unless `dense_enabled` is off (`facescan recon --sparse`), the dense surface between 8 and
// 10: dense matching per pair seeded by its sparse model (dense.hpp), registered by stage 8's
// motions, fused over the view sphere (surface.hpp). The sparse mesh is then only reported.
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "pattern/pattern.hpp"
#include "recon/bundle.hpp"
#include "recon/debug.hpp"
#include "recon/dense.hpp"
#include "recon/fusion.hpp"
#include "recon/image_stages.hpp"
#include "recon/meshing.hpp"
#include "recon/registration.hpp"
#include "recon/surface.hpp"
#include "recon/texture.hpp"
#include "recon/triangulate.hpp"
#include "recon/types.hpp"

#include <string>
#include <vector>

namespace facescan::recon {

struct ReconParams {
	DetectParams detect;
	MatchParams match;
	BundleParams bundle;
	TriangulateParams triangulate;
	MeshingParams meshing;
	RegistrationParams registration;
	FusionParams fusion;
	TextureParams texture;
	DenseParams dense;
	SurfaceParams surface;
	bool texture_enabled = true;
	/// Off: the paper's sparse mesh is the output (`--sparse`).
	bool dense_enabled = true;
	/// A camera whose frame yields fewer decoded squares than this has "no pattern": its pairs run
	/// unseeded; the scan fails only when no pair has the pattern in both views.
	int min_decoded_squares = 12;
	/// Frames whose intensity standard deviation is below this are blank (all white/black).
	double min_frame_stddev = 2.0;
};

struct StageTime {
	std::string name;
	double ms = 0;
};

struct CameraReport {
	int camera = -1;
	int detected = 0, decoded = 0, corrected = 0, rejected = 0, with_corners = 0;
};

struct PairReport {
	int cam_a = -1, cam_b = -1;
	int matches = 0, centroid_matches = 0, corner_matches = 0;
	int rejected_epipolar = 0, rejected_ambiguous = 0;
	int grown = 0;	// squares matched by growing along the grid
	int guided = 0; // ... by guided search along the epipolar line
	int seeded = 0; // ... seeds of growth into parts of the grid nothing else reached
	int pruned = 0; // grown, guided or centroid-only squares dropped as off their neighbours' surface
	TriangulateStats triangulate;
	MeshingStats meshing;
	DenseStats dense;
	/// Why the pair's dense stage failed (empty: it did not). The scan goes on without its cloud.
	std::string dense_error;
};

struct ReconReport {
	std::string scan_id, pattern_id;
	std::vector<StageTime> stages; // in order; "total" last
	std::vector<CameraReport> cameras;
	std::vector<PairReport> pairs;
	BundleStats bundle; // stage 6a: the extrinsics refined on the scan's matches
	BundleStats bundle_dense; // ... again, with the dense clouds' three-view tracks
	std::vector<RegistrationPair> registration;
	FusionStats fusion;   // the sparse mesh
	SurfaceStats surface; // the dense one (when dense matching ran)
	bool dense = false;   // the output is the dense surface
	int sparse_vertices = 0, sparse_triangles = 0;
	TextureStats texture;
	/// Matched points (centroids + corners) over matched centroids, over the squares matched by
	/// their code word: the paper's ~5x.
	double corner_multiplier = 0;
	/// Matched points over matched centroids counting the grown squares too (fewer corners).
	double points_per_square = 0;
	int vertices = 0, triangles = 0;
	long peak_rss_kb = 0; // filled by the caller (getrusage) when it wants it reported
};

/// Reconstructs the face of `set` projected with `pattern`. Checks its input first: at least
/// two cameras, one frame per camera matching its calibrated size, no blank frame, and a
/// pattern found in every frame; each failure names the camera and the cause.
/// `ret_debug`, when given, receives the overlays `facescan recon --debug` writes (debug.hpp); it
/// is filled as far as the pipeline got, also when it fails.
Status reconstruct(const CaptureSet &set, const Pattern &pattern, const ReconParams &params, Mesh *ret_mesh,
		   ReconReport *ret_report, ReconDebug *ret_debug = nullptr);

/// The report as JSON text (keys documented in docs/recon.md).
std::string report_json(const ReconReport &report);

} // namespace facescan::recon
