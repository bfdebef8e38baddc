// Camera calibration from images of a planar target: intrinsics per camera, then every camera's
// pose in one world frame. The library behind `facescan calibrate` (docs/calibration.md).
//
// Data flows one way: image → BoardView (detect_board, per camera and board pose)
//                     → calibrate_rig (per-camera intrinsics, chained pair extrinsics, joint
//                       refinement) → Calibration + RigReport.
// Nothing here reads or writes files or logs; the CLI does that at the edges.
//
// World frame: by default camera 0's frame (x right, y down, z along its optical axis, mm), so
// camera 0 has R = I, T = 0. With CalibParams::origin_pose = k the world is the board's frame in
// pose k instead (origin at its first inner corner, x along its rows, y along its columns, z into
// the board).
#pragma once

#include "capture/capture_set.hpp"
#include "common/status.hpp"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace facescan::calib {

enum class TargetType { Chessboard, Charuco };

/// The calibration target. `cols` x `rows` count INNER corners for both types: a chessboard of
/// (cols+1) x (rows+1) squares, or a ChArUco board of (cols+1) x (rows+1) squares whose white
/// squares hold markers of `dictionary` (OpenCV's cv::aruco::PREDEFINED_DICTIONARY_NAME).
/// Chessboard convention (as OpenCV's printable pattern): the outer square at the corner next to
/// inner corner 0 is black; cols + rows must be odd so that a half turn of the board is seen.
struct BoardSpec {
	TargetType type = TargetType::Chessboard;
	int cols = 9, rows = 6;
	double square_mm = 25;
	double marker_mm = 0;	// ChArUco only: marker side, < square_mm
	int dictionary = 6;	// ChArUco only: cv::aruco::DICT_5X5_1000 (= 6) by default
};

/// Checks a board description; -EINVAL with the reason (e.g. a half-turn-symmetric chessboard).
Status validate_board(const BoardSpec &board);
/// Parses "COLSxROWS" (inner corners), e.g. "9x6".
Status parse_board_size(const std::string &text, int *ret_cols, int *ret_rows);
/// Parses a dictionary name such as "DICT_5X5_1000" or "5X5_1000" into OpenCV's enum value.
Status parse_dictionary(const std::string &text, int *ret_dictionary);
/// Object coordinates (mm, z = 0) of every inner corner, indexed by corner id
/// (id = row * cols + col; origin at corner 0, x along a row, y along a column).
std::vector<cv::Point3f> board_object_points(const BoardSpec &board);

/// The target as seen in one image of one camera.
struct BoardView {
	bool found = false;
	std::string reason;			// why not found (empty when found)
	std::vector<int> ids;			// corner ids, ascending
	std::vector<cv::Point2f> image_points;	// distorted pixels, one per id
	std::vector<cv::Point3f> object_points;	// board mm, one per id
};

enum class ChessboardDetector { SectorBased, Classic };

struct DetectParams {
	/// findChessboardCornersSB (default) or findChessboardCorners + cornerSubPix.
	ChessboardDetector detector = ChessboardDetector::SectorBased;
	int min_charuco_corners = 8;	// fewer interpolated ChArUco corners → not found
	/// Wider images are searched for the chessboard at this width, and its corners refined
	/// with cornerSubPix at full size (the sector-based detector is slow on large images).
	/// A very large value searches at full size.
	int max_search_width = 1000;
};

/// Detects the board in an 8-bit image (gray or BGR). Chessboard corners are put in the board's
/// canonical order (see BoardSpec), so that every camera numbers the corners alike.
BoardView detect_board(const cv::Mat &image, const BoardSpec &board,
		       const DetectParams &params = DetectParams());

struct CalibParams {
	int min_views_per_camera = 4;	// board views with the target found, per camera
	int min_views_per_pair = 2;	// poses both cameras of a consecutive pair saw
	/// A view whose RMS after the camera's own calibration exceeds this is dropped (misdetection).
	double max_view_rms_px = 2.0;
	int max_iterations = 100;	// joint refinement (Levenberg–Marquardt)
	int origin_pose = -1;		// -1: world = camera 0; k ≥ 0: world = the board in pose k
};

struct CameraReport {
	int views = 0;			// views used
	double intrinsic_rms_px = 0;	// calibrateCamera on this camera alone
	double final_rms_px = 0;	// after the joint refinement
};

struct PairReport {
	int cam_a = 0, cam_b = 0;
	int views = 0;			// poses both saw
	double chain_rms_px = 0;	// stereoCalibrate with the per-camera intrinsics fixed
	/// After the joint refinement, over the poses both saw, as stereoCalibrate reports it:
	/// sqrt(sum of squared 2-D errors of both cameras / (2 * corners)).
	double final_rms_px = 0;
};

struct RigReport {
	std::vector<CameraReport> cameras;
	std::vector<PairReport> pairs;
	double final_rms_px = 0;	// all observations after the joint refinement
	int iterations = 0;
	int observations = 0;		// corner observations in the joint refinement
	std::string world_frame;	// one sentence: what the world frame is
	/// Views dropped during calibration: "pose P camera C: reason".
	std::vector<std::string> dropped;
};

/// Calibrates a rig from views[pose][camera] (views with found == false are ignored; a camera
/// may miss some poses) and the image size of each camera. Consecutive cameras (0-1, 1-2, ...)
/// must share views. On success fills *ret_calibration (one CameraModel per camera, units mm)
/// and *ret_report; on failure leaves them untouched and returns -EINVAL (too few views, no
/// shared views) or -EDOM (the optimisation diverged).
Status calibrate_rig(const std::vector<std::vector<BoardView>> &views,
		     const std::vector<cv::Size> &sizes, const CalibParams &params,
		     Calibration *ret_calibration, RigReport *ret_report);

} // namespace facescan::calib
