// A simulated scan of the default scene for end-to-end tests: pattern frames only (texture
// frames off, to keep the tests short) and the ground-truth head as a recon::Mesh to score
// against (host/eval).
#pragma once

#include "recon/types.hpp"
#include "sim/sim.hpp"

namespace facescan::testing {

struct SimulatedScan {
	Pattern pattern;
	CaptureSet set;
	recon::Mesh truth; // the head, world mm
};

/// Renders the default scene with head `shape` through `rig` (noise seed `seed`).
inline Status simulate_scan(const sim::Rig &rig, const sim::HeadShape &shape, uint64_t seed, SimulatedScan *ret)
{
	sim::Scene scene;
	Status s = sim::scene_by_name("default", &scene);
	if (!s.ok())
		return s;
	scene.head.shape = shape;
	s = default_pattern(SlideSpec(), &ret->pattern);
	if (!s.ok())
		return s;
	sim::SimTruth truth;
	sim::SimOptions options;
	options.texture_frames = false;
	s = sim::simulate(rig, scene, ret->pattern, seed, &ret->set, &truth, options);
	if (!s.ok())
		return s;
	ret->truth = recon::Mesh();
	for (const cv::Vec3f &v : truth.head.vertices)
		ret->truth.positions.emplace_back(v[0], v[1], v[2]);
	ret->truth.triangles = truth.head.triangles;
	return {};
}

} // namespace facescan::testing
