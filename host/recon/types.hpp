// Plain data passed between the reconstruction stages. Data flows one way:
//   frame → CameraDetections (per camera: squares, letters, grid, cell ids, corners)
//         → PairMatches (per consecutive camera pair: matched image points)
//         → PartialModel (per pair: triangulated points + mesh) → fused Mesh.
// Stages are free functions taking the previous stage's data and a Params struct.
#pragma once

#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <vector>

namespace facescan::recon {

/// Features of a square: its centroid and its 4 corners in the slide's sense
/// (top-left, top-right, bottom-right, bottom-left as projected on the slide).
enum Feature : int { kCentroid = 0, kTopLeft = 1, kTopRight = 2, kBottomRight = 3, kBottomLeft = 4 };
constexpr int kFeatureCount = 5;

/// One square detected in one camera image.
struct Square {
	cv::Point2d centroid;			// pixels, distorted image coordinates
	std::array<cv::Point2d, 4> corners{};	// TL, TR, BR, BL (slide sense), sub-pixel
	bool has_corners = false;
	int letter = -1;			// classified code letter, -1 unknown
	float confidence = 0;			// 0..1 of the letter classification
	std::array<int, 4> neighbours{{-1, -1, -1, -1}}; // up, left, right, down: indices or -1
	int cell = -1;		// decoded matrix cell r*cols+c, -1 not decoded
	bool corrected = false; // decoded after correcting a wrong or missing letter
	/// Its shape disagrees with its grid neighbours' (cut by a shadow or an occluding edge, bent
	/// over a lip, two squares run together in a projector seam): its corners are not surface points
	/// of the slide's square. Not matched by its code; growing and guided matching (match.cpp) may
	/// match its centroid, which prune_matches checks against the surface around it.
	bool irregular = false;
	double area = 0;	// pixels
};

struct CameraDetections {
	int camera = -1;
	std::vector<Square> squares;
	// Counts for the report.
	int detected = 0, decoded = 0, corrected = 0, rejected = 0;
};

/// A point seen in both cameras of a pair: the same feature of the same projected square.
struct PointMatch {
	cv::Point2d a, b;	// distorted pixel coordinates in cam_a and cam_b
	int square_a = -1;	// index into cam_a's CameraDetections::squares
	int square_b = -1;	// index into cam_b's
	int feature = kCentroid;
	int cell = -1;		// -1 when neither square's code word was read (a grown match)
	bool grown = false;	// found by growing along the grid, not by its cell id (match.cpp)
};

struct PairMatches {
	int cam_a = -1, cam_b = -1; // consecutive cameras: (0,1), (1,2), (2,3)
	std::vector<PointMatch> matches;
	int rejected_epipolar = 0, rejected_ambiguous = 0;
	int grown = 0; // squares matched by growing along the grid (no usable code word of their own)
	int guided = 0; // squares matched along the epipolar line within their neighbours' depth
	int seeded = 0; // squares that seeded growth into a part of the grid nothing else reached
	int pruned = 0; // grown, guided or centroid-only squares removed as off their neighbours' surface
};

/// One surface point seen by two or more cameras: its distorted pixel in each (index k of
/// `cameras` and `pixels` is one view).
struct Track {
	std::vector<int> cameras;
	std::vector<cv::Point2d> pixels;
};

/// One pair's partial model, points in world mm. Index i of every vector is one point.
struct PartialModel {
	int cam_a = -1, cam_b = -1;
	std::vector<cv::Point3d> points;
	std::vector<PointMatch> sources;	// the match each point came from
	std::vector<double> reprojection_px;	// mean reprojection error per point
	std::vector<cv::Vec3i> triangles;	// indices into points
};

/// The fused face mesh.
struct Mesh {
	std::vector<cv::Point3f> positions;	// mm, calibration world frame
	std::vector<cv::Vec3i> triangles;
	std::vector<cv::Point2f> uvs;		// per vertex, into `texture`; empty without texture
	std::vector<cv::Point3f> normals;	// per vertex, optional
	std::vector<cv::Vec3b> colours;		// per vertex BGR fallback when no texture frames
	cv::Mat texture;			// 8-bit BGR atlas, empty when none
};

} // namespace facescan::recon
