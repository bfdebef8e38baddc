// Stages 1-3 and 5 for one camera frame, in data-flow order.
#include "recon/image_stages.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

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
	// decode_cells rewrites neighbours and corners into the slide's sense: keep the image's.
	const std::vector<Square> read = out.squares;
	link_grid(pattern.slide.gap_fraction, params.grid, &out.squares);
	decode_cells(pattern, params.decode, &out);
	// Superposed copies: a view that decodes few of its squares gets the letters' own planes,
	// their colours measured on the squares read so far (a view with too few squares of some
	// letter keeps the intensity stage's). Only such views: each plane costs as much as the
	// intensity stage. The planes cover the squares' bounding box (the face), widened by two sides.
	std::vector<cv::Vec3d> colours;
	if (params.planes.enabled && pattern.matrix.letters() == 3 && !blobs.empty() &&
	    out.decoded < params.planes.max_decoded_share * out.detected &&
	    letter_colours(bgr, blobs, read, 3, params.gamma, params.planes.min_squares_per_letter, &colours).ok()) {
		cv::Rect face = blobs[0].box;
		std::vector<double> areas;
		for (size_t k = 0; k < blobs.size(); k++) {
			face |= blobs[k].box;
			areas.push_back(read[k].area);
		}
		std::nth_element(areas.begin(), areas.begin() + std::ptrdiff_t(areas.size() / 2), areas.end());
		const int pad = int(2 * std::sqrt(areas[areas.size() / 2]));
		face = cv::Rect(face.x - pad, face.y - pad, face.width + 2 * pad, face.height + 2 * pad) &
		       cv::Rect(0, 0, bgr.cols, bgr.rows);
		// find_squares derives its first window from the image's size: the frame's, not the crop's.
		SquareParams plane_squares = params.squares;
		plane_squares.first_window_px = first_window_px(params.squares, bgr.size());
		std::vector<cv::Mat> planes;
		if (letter_planes(bgr(face), params.gamma, colours, params.planes.min_share, &planes).ok()) {
			CameraDetections again;
			again.camera = out.camera;
			again.squares = read;
			st = add_letter_squares(planes, face.tl(), plane_squares, params.corners, params.planes,
						&again.squares, &blobs);
			if (!st.ok())
				return st;
			link_grid(pattern.slide.gap_fraction, params.grid, &again.squares);
			decode_cells(pattern, params.decode, &again);
			out = std::move(again);
		}
	}
	check_grid_shapes(params.grid, &out.squares);
	*ret = std::move(out);
	return {};
}

} // namespace facescan::recon
