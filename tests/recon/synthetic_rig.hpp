// Test helper: a 4-camera booth ring with lens distortion and exact matches of known surfaces.
// World frame: x right, y up, z from the face towards the middle cameras (mm).
#pragma once

#include "capture/capture_set.hpp"
#include "recon/triangulate.hpp"
#include "recon/types.hpp"

#include <cmath>
#include <random>
#include <vector>

namespace synth {

using facescan::CameraModel;
using facescan::recon::PairMatches;
using facescan::recon::PointMatch;

inline CameraModel camera_at(double azimuth_deg, double distance = 550)
{
	const double a = azimuth_deg * CV_PI / 180.0;
	const cv::Vec3d C(distance * std::sin(a), 30, distance * std::cos(a));
	const cv::Vec3d z = -C * (1.0 / cv::norm(C));
	cv::Vec3d x = cv::Vec3d(0, 1, 0).cross(z);
	x *= 1.0 / cv::norm(x);
	const cv::Vec3d y = z.cross(x); // image down
	CameraModel cam;
	cam.R = cv::Matx33d(x[0], x[1], x[2], y[0], y[1], y[2], z[0], z[1], z[2]);
	cam.T = -(cam.R * C);
	cam.K = cv::Matx33d(2000, 0, 800, 0, 2000, 600, 0, 0, 1);
	cam.dist = cv::Vec<double, 5>(-0.12, 0.08, 0.0008, -0.0005, 0.0);
	cam.size = cv::Size(1600, 1200);
	return cam;
}

inline std::vector<CameraModel> ring()
{
	return {camera_at(-60), camera_at(-20), camera_at(20), camera_at(60)};
}

/// True when camera c sees point p on a surface with outward normal n (front-facing, in frame).
inline bool sees(const CameraModel &c, const cv::Point3d &p, const cv::Vec3d &n)
{
	const cv::Vec3d v = c.centre() - cv::Vec3d(p);
	if (n.dot(v) / cv::norm(v) < 0.2)
		return false;
	const std::vector<cv::Point2d> px = facescan::recon::project_points(c, {p});
	return px[0].x > 0 && px[0].y > 0 && px[0].x < c.size.width && px[0].y < c.size.height;
}

/// Matches of `points` (outward normals `normals`) between cameras a and b with Gaussian pixel
/// noise. Square index in every camera = point index, so models sharing a camera link up.
inline PairMatches matches(const std::vector<CameraModel> &cams, int a, int b, const std::vector<cv::Point3d> &points,
			   const std::vector<cv::Vec3d> &normals, double noise_px, unsigned seed)
{
	std::mt19937 rng(seed);
	std::normal_distribution<double> noise(0.0, noise_px);
	PairMatches pm;
	pm.cam_a = a;
	pm.cam_b = b;
	const std::vector<cv::Point2d> pa = facescan::recon::project_points(cams[size_t(a)], points);
	const std::vector<cv::Point2d> pb = facescan::recon::project_points(cams[size_t(b)], points);
	for (size_t i = 0; i < points.size(); ++i) {
		if (!sees(cams[size_t(a)], points[i], normals[i]) || !sees(cams[size_t(b)], points[i], normals[i]))
			continue;
		PointMatch m;
		m.a = pa[i] + cv::Point2d(noise(rng), noise(rng));
		m.b = pb[i] + cv::Point2d(noise(rng), noise(rng));
		m.square_a = m.square_b = int(i);
		m.feature = facescan::recon::kCentroid;
		m.cell = int(i);
		pm.matches.push_back(m);
	}
	return pm;
}

/// Points on the front cap of a sphere (centre c, radius r), on a regular azimuth/elevation grid.
inline void sphere(const cv::Point3d &c, double r, double step_deg, std::vector<cv::Point3d> *pts,
		   std::vector<cv::Vec3d> *normals)
{
	for (double el = -50; el <= 50 + 1e-9; el += step_deg)
		for (double az = -85; az <= 85 + 1e-9; az += step_deg) {
			const double e = el * CV_PI / 180, a = az * CV_PI / 180;
			const cv::Vec3d n(std::cos(e) * std::sin(a), std::sin(e), std::cos(e) * std::cos(a));
			pts->push_back(c + cv::Point3d(n * r));
			normals->push_back(n);
		}
}

/// Least-squares sphere (algebraic): returns the radius, centre in *c.
inline double fit_sphere(const std::vector<cv::Point3d> &p, cv::Point3d *c)
{
	cv::Mat A(int(p.size()), 4, CV_64F), b(int(p.size()), 1, CV_64F);
	for (int i = 0; i < int(p.size()); ++i) {
		A.at<double>(i, 0) = 2 * p[size_t(i)].x;
		A.at<double>(i, 1) = 2 * p[size_t(i)].y;
		A.at<double>(i, 2) = 2 * p[size_t(i)].z;
		A.at<double>(i, 3) = 1;
		b.at<double>(i) = p[size_t(i)].dot(p[size_t(i)]);
	}
	cv::Mat x;
	cv::solve(A, b, x, cv::DECOMP_SVD);
	*c = cv::Point3d(x.at<double>(0), x.at<double>(1), x.at<double>(2));
	return std::sqrt(x.at<double>(3) + c->dot(*c));
}

} // namespace synth
