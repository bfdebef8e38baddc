// Ray casting against triangle meshes (Embree 3): the one ray caster of the project, used by the
// booth simulator (rendering, coverage) and by the scan previews (thumbnails). Plain data in.
#pragma once

#include "common/status.hpp"

#include <opencv2/core.hpp>

#include <memory>
#include <vector>

namespace facescan::raycast {

/// One triangle mesh of a scene; build() copies it.
struct Geometry {
	const std::vector<cv::Vec3f> *vertices = nullptr; // mm
	const std::vector<cv::Vec3i> *triangles = nullptr;
};

struct Hit {
	float t = 0;		// distance along the (normalised) ray, mm
	int surface = -1;	// index of the geometry in build()'s vector, -1 = miss
	int triangle = -1;
	float u = 0, v = 0;	// barycentrics of vertices 1 and 2
};

/// An Embree scene over a set of meshes. Move-only; queries are thread-safe.
class Tracer {
public:
	Tracer();
	~Tracer();
	Tracer(Tracer &&) noexcept;
	Tracer &operator=(Tracer &&) noexcept;
	Tracer(const Tracer &) = delete;
	Tracer &operator=(const Tracer &) = delete;

	/// -EINVAL for an empty or malformed mesh (index out of range, non-finite vertex), naming
	/// it; -ENOMEM / -EIO when Embree fails. A failed build leaves the tracer as it was.
	Status build(const std::vector<Geometry> &geometries);
	/// Closest hit along origin + t * normalize(dir) for t in (t_near, t_far), t in mm.
	Hit intersect(const cv::Vec3d &origin, const cv::Vec3d &dir, double t_near = 0, double t_far = 1e30) const;
	/// True when anything lies between origin and origin + t_far * normalize(dir).
	bool occluded(const cv::Vec3d &origin, const cv::Vec3d &dir, double t_near, double t_far) const;

private:
	struct Impl;
	std::unique_ptr<Impl> impl_;
};

} // namespace facescan::raycast
