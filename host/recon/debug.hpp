// What `facescan recon --debug DIR` shows: per camera the detected squares, their letters, cell
// ids, corners and grid links; per pair the matches and the dense stage's prior, disparity and
// accepted pixels; the dense clouds. Built in memory by the pipeline (no file I/O here); the CLI
// writes each image as DIR/<name>.png and each cloud as DIR/<name>.ply.
#pragma once

#include "recon/types.hpp"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace facescan::recon {

struct DebugImage {
	std::string name; // file stem, e.g. "cam0_squares"
	cv::Mat image;	  // 8-bit BGR
};

struct DebugCloud {
	std::string name; // e.g. "pair0_dense"
	std::vector<cv::Point3f> points;
	std::vector<float> value; // per point (confidence), shown as a colour
};

struct DebugText {
	std::string name; // file name with its extension, e.g. "pair0_rectification.yaml"
	std::string text;
};

struct ReconDebug {
	std::vector<DebugImage> images;
	std::vector<DebugCloud> clouds;
	std::vector<DebugText> texts;
};

/// The frame with each square's outline (its letter's colour; grey when unknown), its cell id,
/// corners (dots) and grid links (thin lines); irregular squares dashed in white.
cv::Mat draw_detections(const cv::Mat &frame, const CameraDetections &dets);

/// Both frames side by side (each halved) with the pair's matches: code-word matches green,
/// grown / guided / seeded ones yellow, one line per matched centroid.
cv::Mat draw_matches(const cv::Mat &frame_a, const cv::Mat &frame_b, const PairMatches &pm);

/// A float map (NaN = none) as a colour image: the finite range [lo, hi] through a colour map,
/// black where there is no value.
cv::Mat colour_map(const cv::Mat &values, double lo, double hi);

} // namespace facescan::recon
