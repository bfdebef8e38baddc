// Stages 1-3 and 5 for one camera frame, in data-flow order.
#include "recon/image_stages.hpp"

#include <opencv2/imgproc.hpp>

namespace facescan::recon {

Status detect_squares(const cv::Mat &bgr, const Pattern &pattern, const DetectParams &params,
		      CameraDetections *ret)
{
	if (bgr.empty() || bgr.type() != CV_8UC3)
		return Status::error(EINVAL, "detect_squares needs a non-empty 8-bit BGR frame");
	if (pattern.matrix.rows() < 3 || pattern.matrix.cols() < 3 || pattern.matrix.letters() < 2)
		return Status::error(EINVAL, "detect_squares: the pattern has no decodable cells");
	cv::Mat raw, intensity;
	Status st = bgr_to_intensity(bgr, &raw, params.gamma);
	if (!st.ok())
		return st;
	// Light smoothing: less noise in the thresholds and edge profiles, and a symmetric blur
	// leaves straight edges where they were.
	cv::GaussianBlur(raw, intensity, cv::Size(5, 5), 1.0, 1.0, cv::BORDER_REPLICATE);
	CameraDetections out;
	out.camera = ret->camera;
	std::vector<SquareBlob> blobs;
	st = find_squares(intensity, params.squares, &out.squares, &blobs);
	if (!st.ok())
		return st;
	detect_corners(intensity, blobs, params.corners, &out.squares);
	HueParams hue = params.hue;
	hue.gamma = params.gamma;
	st = classify_letters(bgr, blobs, pattern, hue, &out.squares);
	if (!st.ok())
		return st;
	// Superposed copies: the letters' own planes, measured on the squares read so far. A view
	// with too few squares of some letter to measure its colour keeps the intensity stage's.
	std::vector<cv::Vec3d> colours;
	if (params.planes.enabled && pattern.matrix.letters() == 3 &&
	    letter_colours(bgr, blobs, out.squares, 3, params.gamma, params.planes.min_squares_per_letter, &colours).ok()) {
		std::vector<cv::Mat> planes;
		if (letter_planes(bgr, params.gamma, colours, params.planes.min_share, &planes).ok()) {
			st = add_letter_squares(planes, params.squares, params.corners, params.planes, &out.squares, &blobs);
			if (!st.ok())
				return st;
		}
	}
	link_grid(pattern.slide.gap_fraction, params.grid, &out.squares);
	decode_cells(pattern, params.decode, &out);
	check_grid_shapes(params.grid, &out.squares);
	*ret = std::move(out);
	return {};
}

} // namespace facescan::recon
