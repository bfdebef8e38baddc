// Synthetic camera views of the slide for the image-stage tests: the slide warped by a homography
// plus a smooth distortion, rendered 8x supersampled, then tinted, shaded, blurred and noised.
// The truth (every cell's corners in the image) comes from the same analytic warp.
#pragma once

#include "pattern/pattern.hpp"
#include "recon/types.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace synth {

struct Warp {
	cv::Matx33d H = cv::Matx33d::eye(); // slide units (1024 x 768 slide) → image pixels
	double amp = 0;			    // smooth distortion amplitude, pixels
	double wavelength = 500;	    // pixels

	cv::Point2d distort(const cv::Point2d &u) const
	{
		double k = 2 * M_PI / wavelength;
		return {amp * std::sin(k * u.y + 0.3), amp * std::sin(k * u.x + 1.1)};
	}
	cv::Point2d fwd(const cv::Point2d &s) const
	{
		cv::Vec3d h = H * cv::Vec3d(s.x, s.y, 1);
		cv::Point2d u(h[0] / h[2], h[1] / h[2]);
		return u + distort(u);
	}
	cv::Point2d inv(const cv::Point2d &p) const
	{
		cv::Point2d u = p;
		for (int k = 0; k < 12; k++)
			u = p - distort(u);
		cv::Vec3d h = H.inv() * cv::Vec3d(u.x, u.y, 1);
		return {h[0] / h[2], h[1] / h[2]};
	}
};

struct Look {
	cv::Size size{800, 600};
	cv::Vec3d albedo{1, 1, 1}; // B G R reflectance
	double ambient = 8;	   // grey light added everywhere
	double shading = 0;	   // left-to-right multiplicative falloff, 0..1
	double blur = 0.8;	   // Gaussian sigma, pixels
	double noise = 1.5;	   // Gaussian sigma, grey levels
	double gamma = 2.2;	   // output encoding, as a camera does: 255 * (v / 255)^(1 / gamma)
	uint64_t seed = 1;
};

/// Homography taking the slide to an image region with a perspective tilt and rotation.
inline cv::Matx33d homography(const facescan::Pattern &p, cv::Size size, double scale,
			      double rot_deg, double tilt)
{
	double a = rot_deg * M_PI / 180, c = std::cos(a), s = std::sin(a);
	double cx = p.slide.width / 2.0, cy = p.slide.height / 2.0;
	cv::Matx33d centre(1, 0, -cx, 0, 1, -cy, 0, 0, 1);
	cv::Matx33d rs(scale * c, -scale * s, 0, scale * s, scale * c, 0, tilt / p.slide.width, 0, 1);
	cv::Matx33d place(1, 0, size.width / 2.0, 0, 1, size.height / 2.0, 0, 0, 1);
	return place * rs * centre;
}

inline cv::Mat render(const facescan::Pattern &p, const Warp &w, const Look &look)
{
	const int ss = 2, up = 4; // image supersampling, slide upsampling
	facescan::SlideSpec big = p.slide;
	big.width *= up;
	big.height *= up;
	facescan::Pattern hp;
	facescan::make_pattern(p.matrix, 0, big, &hp);
	cv::Mat slide = facescan::render_slide(hp);
	cv::Mat mx(look.size.height * ss, look.size.width * ss, CV_32F), my(mx.size(), CV_32F);
	for (int y = 0; y < mx.rows; y++)
		for (int x = 0; x < mx.cols; x++) {
			cv::Point2d s = w.inv({(x - 0.5 * (ss - 1)) / ss, (y - 0.5 * (ss - 1)) / ss});
			mx.at<float>(y, x) = float(s.x * up - 0.5);
			my.at<float>(y, x) = float(s.y * up - 0.5);
		}
	cv::Mat hi, img;
	cv::remap(slide, hi, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
	cv::resize(hi, img, look.size, 0, 0, cv::INTER_AREA);
	cv::Mat f;
	img.convertTo(f, CV_32FC3);
	for (int y = 0; y < f.rows; y++)
		for (int x = 0; x < f.cols; x++) {
			cv::Vec3f &v = f.at<cv::Vec3f>(y, x);
			double shade = 1 - look.shading * x / f.cols;
			for (int c = 0; c < 3; c++)
				v[c] = float((v[c] + look.ambient) * look.albedo[c] * shade);
		}
	if (look.blur > 0)
		cv::GaussianBlur(f, f, cv::Size(0, 0), look.blur);
	cv::Mat n(f.size(), CV_32FC3);
	cv::RNG rng(look.seed);
	rng.fill(n, cv::RNG::NORMAL, 0, look.noise);
	f += n;
	for (int y = 0; y < f.rows; y++)
		for (int x = 0; x < f.cols; x++) {
			cv::Vec3f &v = f.at<cv::Vec3f>(y, x);
			for (int c = 0; c < 3; c++)
				v[c] = float(255.0 * std::pow(std::clamp(v[c] / 255.0, 0.0, 1.0), 1.0 / look.gamma));
		}
	cv::Mat out;
	f.convertTo(out, CV_8UC3);
	return out;
}

struct Truth {
	int cell;
	std::array<cv::Point2d, 4> corners; // TL TR BR BL
	cv::Point2d centre;		    // the diagonals' intersection
};

/// Cells whose square lies fully inside the image (with a margin).
inline std::vector<Truth> truth(const facescan::Pattern &p, const Warp &w, cv::Size size,
				double margin = 4)
{
	std::vector<Truth> out;
	for (int r = 0; r < p.matrix.rows(); r++)
		for (int c = 0; c < p.matrix.cols(); c++) {
			cv::Rect2d rc = p.cell_rect(r, c);
			Truth t;
			t.cell = r * p.matrix.cols() + c;
			t.corners = {w.fwd({rc.x, rc.y}), w.fwd({rc.x + rc.width, rc.y}),
				     w.fwd({rc.x + rc.width, rc.y + rc.height}), w.fwd({rc.x, rc.y + rc.height})};
			bool in = true;
			for (const auto &q : t.corners)
				in = in && q.x > margin && q.y > margin && q.x < size.width - margin &&
				     q.y < size.height - margin;
			if (!in)
				continue;
			t.centre = w.fwd({rc.x + rc.width / 2, rc.y + rc.height / 2});
			out.push_back(t);
		}
	return out;
}

/// Index of the truth cell nearest to a point, -1 when none is within `radius`.
inline int nearest(const std::vector<Truth> &t, const cv::Point2d &p, double radius)
{
	int best = -1;
	double bd = radius;
	for (size_t k = 0; k < t.size(); k++) {
		double d = cv::norm(t[k].centre - p);
		if (d < bd) {
			bd = d;
			best = int(k);
		}
	}
	return best;
}

} // namespace synth
