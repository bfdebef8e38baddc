// Stage 10: texture. Each triangle takes its texture from the camera that sees it most
// frontally (and unoccluded, by a z-buffer of the mesh itself). Each camera's used region is
// cropped from its texture frame into one atlas; vertices on the border between two cameras'
// charts are duplicated (same position, one UV per chart). Without texture frames, per-vertex
// colours are sampled from the pattern frames instead (the fallback).
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"
#include "recon/types.hpp"

#include <vector>

namespace facescan::recon {

struct TextureParams {
	double min_cos = 0.15;		// a camera must see a triangle at least this frontally
	double depth_scale = 0.25;	// z-buffer resolution relative to the camera
	double occlusion_tolerance_mm = 3.0;
	int padding_px = 4;		// around each camera's chart in the atlas
	int max_atlas_width = 4096;	// charts are scaled down to fit
};

struct TextureStats {
	int charts = 0;			// cameras whose texture is used
	int untextured = 0;		// triangles no camera sees (they take the best-facing camera)
	int vertices_before = 0, vertices_after = 0; // the split at chart borders adds vertices
	cv::Size atlas;
	bool vertex_colours = false;	// the fallback was used
};

/// Fills mesh->uvs and mesh->texture from `textures` (one 8-bit BGR frame per camera), or
/// mesh->colours from `frames` when `textures` is empty. Triangles keep their order.
Status texture_mesh(const std::vector<cv::Mat> &textures, const std::vector<cv::Mat> &frames,
		    const std::vector<CameraModel> &cameras, const TextureParams &params, Mesh *mesh,
		    TextureStats *ret_stats);

} // namespace facescan::recon
