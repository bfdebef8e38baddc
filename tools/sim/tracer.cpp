// The simulator's surfaces on the project's ray caster (host/raycast), and pixel rays.
#include "sim/internal.hpp"

#include <opencv2/calib3d.hpp>

#include <cmath>

namespace facescan::sim {

Status build_tracer(const std::vector<Surface> &surfaces, Tracer *tracer)
{
	std::vector<raycast::Geometry> geometries;
	for (size_t i = 0; i < surfaces.size(); i++) {
		Status st = internal::check_mesh(surfaces[i].mesh, "surface " + std::to_string(i));
		if (!st.ok())
			return st;
		geometries.push_back({&surfaces[i].mesh.vertices, &surfaces[i].mesh.triangles});
	}
	return tracer->build(geometries);
}

void pixel_ray(const CameraModel &camera, const cv::Point2d &pixel, cv::Vec3d *ret_origin,
	       cv::Vec3d *ret_dir)
{
	std::vector<cv::Point2d> in{pixel}, out;
	cv::undistortPoints(in, out, camera.K, camera.dist, cv::noArray(), cv::noArray(),
			    cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
	cv::Vec3d d = camera.R.t() * cv::Vec3d(out[0].x, out[0].y, 1.0);
	*ret_origin = camera.centre();
	*ret_dir = d * (1.0 / std::sqrt(d.dot(d)));
}

} // namespace facescan::sim
