// Ray casting with Embree 3: one triangle geometry per surface, geometry id = surface index.
#include "sim/internal.hpp"

#include <embree3/rtcore.h>
#include <opencv2/calib3d.hpp>

#include <cmath>
#include <limits>

namespace facescan::sim {

struct Tracer::Impl {
	RTCDevice device = nullptr;
	RTCScene scene = nullptr;
	~Impl()
	{
		if (scene)
			rtcReleaseScene(scene);
		if (device)
			rtcReleaseDevice(device);
	}
};

Tracer::Tracer() = default;
Tracer::~Tracer() = default;
Tracer::Tracer(Tracer &&) noexcept = default;
Tracer &Tracer::operator=(Tracer &&) noexcept = default;

Status Tracer::build(const std::vector<Surface> &surfaces)
{
	for (size_t i = 0; i < surfaces.size(); i++) {
		Status st = internal::check_mesh(surfaces[i].mesh, "surface " + std::to_string(i));
		if (!st.ok())
			return st;
	}
	auto impl = std::make_unique<Impl>();
	impl->device = rtcNewDevice(nullptr);
	if (!impl->device)
		return Status::error(-ENOMEM, "embree: cannot create a device");
	impl->scene = rtcNewScene(impl->device);
	if (!impl->scene)
		return Status::error(-ENOMEM, "embree: cannot create a scene");
	rtcSetSceneBuildQuality(impl->scene, RTC_BUILD_QUALITY_HIGH);
	for (size_t i = 0; i < surfaces.size(); i++) {
		const Mesh &m = surfaces[i].mesh;
		RTCGeometry g = rtcNewGeometry(impl->device, RTC_GEOMETRY_TYPE_TRIANGLE);
		if (!g)
			return Status::error(-ENOMEM, "embree: cannot create a geometry");
		auto *vb = static_cast<float *>(rtcSetNewGeometryBuffer(
			g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.vertices.size()));
		auto *ib = static_cast<unsigned *>(rtcSetNewGeometryBuffer(
			g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m.triangles.size()));
		if (!vb || !ib) {
			rtcReleaseGeometry(g);
			return Status::error(-ENOMEM, "embree: cannot allocate geometry buffers");
		}
		for (size_t v = 0; v < m.vertices.size(); v++)
			for (int k = 0; k < 3; k++)
				vb[3 * v + size_t(k)] = m.vertices[v][k];
		for (size_t t = 0; t < m.triangles.size(); t++)
			for (int k = 0; k < 3; k++)
				ib[3 * t + size_t(k)] = unsigned(m.triangles[t][k]);
		rtcCommitGeometry(g);
		rtcAttachGeometryByID(impl->scene, g, unsigned(i));
		rtcReleaseGeometry(g);
	}
	rtcCommitScene(impl->scene);
	if (rtcGetDeviceError(impl->device) != RTC_ERROR_NONE)
		return Status::error(-EIO, "embree: building the scene failed");
	impl_ = std::move(impl);
	return Status();
}

static void fill_ray(RTCRay *ray, const cv::Vec3d &o, const cv::Vec3d &dir, double t_near,
		     double t_far)
{
	cv::Vec3d d = dir * (1.0 / std::sqrt(dir.dot(dir)));
	ray->org_x = float(o[0]);
	ray->org_y = float(o[1]);
	ray->org_z = float(o[2]);
	ray->dir_x = float(d[0]);
	ray->dir_y = float(d[1]);
	ray->dir_z = float(d[2]);
	ray->tnear = float(t_near);
	ray->tfar = t_far > 3e38 ? std::numeric_limits<float>::infinity() : float(t_far);
	ray->mask = 0xffffffffu;
	ray->flags = 0;
	ray->time = 0;
	ray->id = 0;
}

Hit Tracer::intersect(const cv::Vec3d &origin, const cv::Vec3d &dir, double t_near,
		      double t_far) const
{
	Hit hit;
	if (!impl_)
		return hit;
	RTCIntersectContext ctx;
	rtcInitIntersectContext(&ctx);
	RTCRayHit rh;
	fill_ray(&rh.ray, origin, dir, t_near, t_far);
	rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
	rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
	rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
	rtcIntersect1(impl_->scene, &ctx, &rh);
	if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID)
		return hit;
	hit.t = rh.ray.tfar;
	hit.surface = int(rh.hit.geomID);
	hit.triangle = int(rh.hit.primID);
	hit.u = rh.hit.u;
	hit.v = rh.hit.v;
	return hit;
}

bool Tracer::occluded(const cv::Vec3d &origin, const cv::Vec3d &dir, double t_near,
		      double t_far) const
{
	if (!impl_)
		return false;
	RTCIntersectContext ctx;
	rtcInitIntersectContext(&ctx);
	RTCRay ray;
	fill_ray(&ray, origin, dir, t_near, t_far);
	rtcOccluded1(impl_->scene, &ctx, &ray);
	return ray.tfar < 0;
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
