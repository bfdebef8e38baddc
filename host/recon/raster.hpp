// A small z-buffer: the depth of a triangle mesh seen through a calibrated camera, used for
// visibility (texture: which camera sees a triangle; evaluation: which cameras see a point).
#pragma once

#include "capture/capture_set.hpp"

#include <opencv2/core.hpp>

#include <vector>

namespace facescan::recon {

/// Renders camera-z depth (mm, CV_32F, +inf where empty) of the triangles at `scale` times the
/// camera's resolution. Vertices are projected with distortion; triangles are filled flat in
/// image space with depth interpolated linearly (fine for small triangles). `pixels`, when given,
/// are the positions' projections (`project_points`), so that a caller who has them does not
/// pay for them again.
cv::Mat render_depth(const CameraModel &cam, const std::vector<cv::Point3f> &positions,
		     const std::vector<cv::Vec3i> &triangles, double scale,
		     const std::vector<cv::Point2d> *pixels = nullptr);

/// Per point (world mm): 1 when it is in front of the camera, inside the image and not behind the
/// depth map by more than `tolerance_mm`. `depth` comes from render_depth at the same scale;
/// `pixels`, when given, are the points' projections (`project_points`).
std::vector<char> visible_in(const CameraModel &cam, const cv::Mat &depth, double scale,
			     const std::vector<cv::Point3d> &points, double tolerance_mm,
			     const std::vector<cv::Point2d> *pixels = nullptr);

} // namespace facescan::recon
