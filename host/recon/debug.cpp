// Debug overlays. See debug.hpp.
#include "recon/debug.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>

namespace facescan::recon {

namespace {

// Colours of the three code letters as the slide's hues look (BGR), then grey for unknown.
cv::Scalar letter_colour(int letter)
{
	static const cv::Scalar colours[] = {{80, 80, 255}, {80, 255, 80}, {255, 160, 60}, {255, 0, 255},
					     {0, 255, 255}};
	if (letter < 0)
		return {160, 160, 160};
	return colours[size_t(letter) % 5];
}

} // namespace

cv::Mat draw_detections(const cv::Mat &frame, const CameraDetections &dets)
{
	cv::Mat out;
	cv::cvtColor(frame, out, cv::COLOR_BGR2GRAY);
	cv::cvtColor(out, out, cv::COLOR_GRAY2BGR);
	out *= 0.6;
	for (const Square &sq : dets.squares)
		for (int k = 0; k < 4; ++k) {
			const int nb = sq.neighbours[size_t(k)];
			if (nb >= 0 && size_t(nb) < dets.squares.size())
				cv::line(out, sq.centroid, dets.squares[size_t(nb)].centroid, {90, 90, 90}, 1, cv::LINE_AA);
		}
	for (const Square &sq : dets.squares) {
		const cv::Scalar c = sq.irregular ? cv::Scalar(255, 255, 255) : letter_colour(sq.letter);
		if (sq.has_corners) {
			for (int k = 0; k < 4; ++k)
				cv::line(out, sq.corners[size_t(k)], sq.corners[size_t((k + 1) % 4)], c, 1, cv::LINE_AA);
			for (const cv::Point2d &p : sq.corners)
				cv::circle(out, p, 2, {0, 255, 255}, -1, cv::LINE_AA);
		} else {
			cv::circle(out, sq.centroid, 4, c, 1, cv::LINE_AA);
		}
		if (sq.cell >= 0)
			cv::putText(out, std::to_string(sq.cell), sq.centroid + cv::Point2d(-6, 3),
				    cv::FONT_HERSHEY_PLAIN, 0.6, sq.corrected ? cv::Scalar(0, 200, 255) : cv::Scalar(255, 255, 255),
				    1, cv::LINE_AA);
	}
	return out;
}

cv::Mat draw_matches(const cv::Mat &frame_a, const cv::Mat &frame_b, const PairMatches &pm)
{
	cv::Mat a, b, out;
	cv::resize(frame_a, a, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
	cv::resize(frame_b, b, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
	if (a.rows != b.rows)
		cv::resize(b, b, cv::Size(b.cols * a.rows / std::max(1, b.rows), a.rows));
	cv::hconcat(a, b, out);
	out *= 0.6;
	const cv::Point2d off(a.cols, 0);
	for (const PointMatch &m : pm.matches) {
		const cv::Scalar c = m.grown ? cv::Scalar(0, 230, 230) : cv::Scalar(0, 230, 0);
		cv::circle(out, m.a * 0.5, 1, c, -1);
		cv::circle(out, m.b * 0.5 + off, 1, c, -1);
		if (m.feature == kCentroid)
			cv::line(out, m.a * 0.5, m.b * 0.5 + off, c * 0.5, 1, cv::LINE_AA);
	}
	return out;
}

cv::Mat colour_map(const cv::Mat &values, double lo, double hi)
{
	cv::Mat v8(values.size(), CV_8U, cv::Scalar(0)), has(values.size(), CV_8U, cv::Scalar(0));
	const double span = hi > lo ? hi - lo : 1;
	for (int y = 0; y < values.rows; ++y) {
		const float *r = values.ptr<float>(y);
		for (int x = 0; x < values.cols; ++x)
			if (std::isfinite(r[x])) {
				v8.at<uchar>(y, x) = cv::saturate_cast<uchar>(1 + 254 * (r[x] - lo) / span);
				has.at<uchar>(y, x) = 255;
			}
	}
	cv::Mat out;
	cv::applyColorMap(v8, out, cv::COLORMAP_TURBO);
	out.setTo(cv::Scalar(0, 0, 0), has == 0);
	return out;
}

} // namespace facescan::recon
