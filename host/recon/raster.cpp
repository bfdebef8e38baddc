// The z-buffer of raster.hpp.
#include "recon/raster.hpp"
#include "recon/triangulate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace facescan::recon {

cv::Mat render_depth(const CameraModel &cam, const std::vector<cv::Point3f> &positions,
		     const std::vector<cv::Vec3i> &triangles, double scale, const std::vector<cv::Point2d> *pixels)
{
	const int w = std::max(1, int(std::lround(cam.size.width * scale)));
	const int h = std::max(1, int(std::lround(cam.size.height * scale)));
	cv::Mat depth(h, w, CV_32F, cv::Scalar(std::numeric_limits<float>::infinity()));
	std::vector<cv::Point3d> pts(positions.begin(), positions.end());
	std::vector<cv::Point2d> px = pixels && pixels->size() == pts.size() ? *pixels : project_points(cam, pts);
	std::vector<double> z(pts.size());
	for (size_t i = 0; i < pts.size(); ++i) {
		const cv::Vec3d c = cam.R * cv::Vec3d(pts[i]) + cam.T;
		z[i] = c[2];
		// Pixel centres at integers: scaled pixel of continuous coordinate x is (x + 0.5) s - 0.5.
		px[i] = cv::Point2d((px[i].x + 0.5) * scale - 0.5, (px[i].y + 0.5) * scale - 0.5);
	}
	for (const cv::Vec3i &t : triangles) {
		const cv::Point2d &a = px[size_t(t[0])], &b = px[size_t(t[1])], &c = px[size_t(t[2])];
		const double za = z[size_t(t[0])], zb = z[size_t(t[1])], zc = z[size_t(t[2])];
		if (za <= 0 || zb <= 0 || zc <= 0)
			continue;
		const double area = (b - a).cross(c - a);
		if (std::fabs(area) < 1e-12)
			continue;
		const int x0 = std::max(0, int(std::ceil(std::min({a.x, b.x, c.x}))));
		const int x1 = std::min(w - 1, int(std::floor(std::max({a.x, b.x, c.x}))));
		const int y0 = std::max(0, int(std::ceil(std::min({a.y, b.y, c.y}))));
		const int y1 = std::min(h - 1, int(std::floor(std::max({a.y, b.y, c.y}))));
		for (int y = y0; y <= y1; ++y) {
			float *row = depth.ptr<float>(y);
			for (int x = x0; x <= x1; ++x) {
				const cv::Point2d p(x, y);
				const double l1 = (c - b).cross(p - b) / area, l2 = (a - c).cross(p - c) / area;
				const double l3 = 1.0 - l1 - l2;
				if (l1 < -1e-9 || l2 < -1e-9 || l3 < -1e-9)
					continue;
				const float d = float(l1 * za + l2 * zb + l3 * zc);
				if (d < row[x])
					row[x] = d;
			}
		}
	}
	return depth;
}

std::vector<char> visible_in(const CameraModel &cam, const cv::Mat &depth, double scale,
			     const std::vector<cv::Point3d> &points, double tolerance_mm,
			     const std::vector<cv::Point2d> *pixels)
{
	std::vector<char> out(points.size(), 0);
	const bool given = pixels && pixels->size() == points.size();
	const std::vector<cv::Point2d> projected = given ? std::vector<cv::Point2d>() : project_points(cam, points);
	const std::vector<cv::Point2d> &px = given ? *pixels : projected;
	for (size_t i = 0; i < points.size(); ++i) {
		const cv::Vec3d c = cam.R * cv::Vec3d(points[i]) + cam.T;
		if (c[2] <= 0)
			continue;
		const int x = int(std::lround((px[i].x + 0.5) * scale - 0.5));
		const int y = int(std::lround((px[i].y + 0.5) * scale - 0.5));
		if (x < 0 || y < 0 || x >= depth.cols || y >= depth.rows)
			continue;
		// The nearest of the 3x3 neighbourhood: a point on a silhouette edge stays visible.
		float best = std::numeric_limits<float>::infinity();
		for (int dy = -1; dy <= 1; ++dy)
			for (int dx = -1; dx <= 1; ++dx) {
				const int xx = std::clamp(x + dx, 0, depth.cols - 1);
				const int yy = std::clamp(y + dy, 0, depth.rows - 1);
				best = std::min(best, depth.at<float>(yy, xx));
			}
		out[i] = !(c[2] > double(best) + tolerance_mm);
	}
	return out;
}

} // namespace facescan::recon
