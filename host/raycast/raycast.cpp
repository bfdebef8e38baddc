// Ray casting with Embree 3: one triangle geometry per mesh, geometry id = its index.
#include "raycast/raycast.hpp"

#include <embree3/rtcore.h>

#include <cmath>
#include <limits>
#include <string>

namespace facescan::raycast {

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

static Status check(const Geometry &g, size_t index)
{
	const std::string what = "ray casting: mesh " + std::to_string(index);
	if (!g.vertices || !g.triangles || g.vertices->empty() || g.triangles->empty())
		return Status::error(EINVAL, what + " is empty");
	const size_t n = g.vertices->size();
	if (n > size_t(INT32_MAX))
		return Status::error(EINVAL, what + " has too many vertices");
	for (size_t i = 0; i < g.triangles->size(); i++)
		for (int k = 0; k < 3; k++) {
			const int v = (*g.triangles)[i][k];
			if (v < 0 || size_t(v) >= n)
				return Status::error(EINVAL, what + ": triangle " + std::to_string(i) +
								     " has vertex index " + std::to_string(v) +
								     " out of range");
		}
	for (const cv::Vec3f &v : *g.vertices)
		if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
			return Status::error(EINVAL, what + " has a non-finite vertex");
	return Status();
}

Status Tracer::build(const std::vector<Geometry> &geometries)
{
	for (size_t i = 0; i < geometries.size(); i++) {
		Status st = check(geometries[i], i);
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
	for (size_t i = 0; i < geometries.size(); i++) {
		const std::vector<cv::Vec3f> &vertices = *geometries[i].vertices;
		const std::vector<cv::Vec3i> &triangles = *geometries[i].triangles;
		RTCGeometry g = rtcNewGeometry(impl->device, RTC_GEOMETRY_TYPE_TRIANGLE);
		if (!g)
			return Status::error(-ENOMEM, "embree: cannot create a geometry");
		auto *vb = static_cast<float *>(rtcSetNewGeometryBuffer(
			g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertices.size()));
		auto *ib = static_cast<unsigned *>(rtcSetNewGeometryBuffer(
			g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles.size()));
		if (!vb || !ib) {
			rtcReleaseGeometry(g);
			return Status::error(-ENOMEM, "embree: cannot allocate geometry buffers");
		}
		for (size_t v = 0; v < vertices.size(); v++)
			for (int k = 0; k < 3; k++)
				vb[3 * v + size_t(k)] = vertices[v][k];
		for (size_t t = 0; t < triangles.size(); t++)
			for (int k = 0; k < 3; k++)
				ib[3 * t + size_t(k)] = unsigned(triangles[t][k]);
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

} // namespace facescan::raycast
