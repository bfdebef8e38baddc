// The simulator's calibration-target images: a chessboard or ChArUco board at a known pose, as
// one camera of a rig sees it (lens distortion, anti-aliased edges, optical blur, sensor noise).
// Used to test `facescan calibrate` end to end against the rig's true cameras.
//
// Rendering is by ray casting: each pixel (or sub-pixel sample) is undistorted to a ray with
// cv::undistortPoints, the ray meets the board plane, and the board's brightness there is
// integrated over the pixel's footprint (exactly for the chessboard, by supersampling a texture
// drawn by OpenCV for ChArUco).
#pragma once

#include "calib/calib.hpp"
#include "capture/capture_set.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <vector>

namespace facescan::sim {

/// A board pose: board → world, x_world = R * x_board + t (mm). Board coordinates as in
/// calib::BoardSpec: origin at inner corner 0, x along a row, y along a column, z into the board.
struct BoardPose {
	cv::Matx33d R = cv::Matx33d::eye();
	cv::Vec3d t = {0, 0, 0};
};

struct BoardRenderParams {
	double black = 25, white = 225;	// board brightness (8-bit)
	double background = 90;		// beyond the board's white margin
	double margin_squares = 1.0;	// white border around the squares, in squares
	double blur_sigma_px = 0.7;	// optics (Gaussian, in pixels; 0 = none)
	double noise_sigma = 2.0;	// sensor noise (8-bit levels; 0 = none)
	uint32_t seed = 1;		// noise seed
};

/// One camera rendering board images; computes the camera's pixel rays once. `supersample`
/// samples per pixel and axis are taken for textured (ChArUco) boards; the chessboard is
/// integrated exactly over each pixel and ignores it. render() is const and thread-safe.
class BoardCamera {
public:
	explicit BoardCamera(const CameraModel &camera, int supersample = 3);
	/// Renders what the camera sees of `board` at `pose`: an 8-bit gray image of the
	/// camera's size. -EINVAL for an invalid board or a camera without a size.
	Status render(const calib::BoardSpec &board, const BoardPose &pose,
		      const BoardRenderParams &params, cv::Mat *ret_image) const;

private:
	CameraModel camera_;
	int supersample_;
	cv::Mat rays_;		// one ray per pixel
	cv::Mat fine_rays_;	// supersample x supersample rays per pixel
};

/// One-off render (BoardCamera without the kept rays).
Status render_board(const CameraModel &camera, const calib::BoardSpec &board,
		    const BoardPose &pose, const BoardRenderParams &params, cv::Mat *ret_image);

/// Board poses for calibrating `rig`: the board's centre near `target` (world mm), turned to
/// face each camera and each point between consecutive cameras, tilted both ways so that every
/// camera gets intrinsic views and every consecutive pair gets shared views. `per_direction`
/// (1..3) poses per direction: tilted up, tilted down, swung sideways. Deterministic.
std::vector<BoardPose> calibration_poses(const Calibration &rig, const calib::BoardSpec &board,
					 const cv::Vec3d &target, int per_direction = 3);

} // namespace facescan::sim
