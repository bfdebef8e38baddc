// A simulated scan of the default scene for end-to-end tests: pattern frames only (texture
// frames off, to keep the tests short) and the ground-truth head as a recon::Mesh to score
// against (host/eval).
#pragma once

#include "recon/types.hpp"
#include "sim/sim.hpp"

#include <cstdlib>
#include <filesystem>
#include <string>
#include <unistd.h>

namespace facescan::testing {

struct SimulatedScan {
	Pattern pattern;
	CaptureSet set;
	recon::Mesh truth;     // the head, world mm
	sim::SimTruth sim_truth; // what sim::write_simulated_set writes beside the set
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
	ret->sim_truth = std::move(truth);
	return {};
}

// ---- the default scan, rendered once per test run ------------------------------------------
// recon/test_e2e and daemon/test_pipeline_recon score the same scan: the default scene with the
// canonical head through the default rig, noise seed 1, pattern frames only (~17 CPU-s of rendering
// in the ASan build). The first to render it leaves it as a simulated set (sim::write_simulated_set) in
// $FACESCAN_TEST_CACHE/default-scan; tests/run-tests.sh makes that directory afresh for every
// run and removes it after, so a set there is never older than the binaries under test. Without
// FACESCAN_TEST_CACHE (a test run by hand) every test renders its own.

/// The default scan: simulate_scan(default rig, canonical head, seed 1).
inline Status simulate_default_scan(SimulatedScan *ret)
{
	return simulate_scan(sim::default_rig(), sim::HeadShape(), 1, ret);
}

/// The default scan's set when a test of this run has left it: true and *ret_dir (read only:
/// other tests read it too); else false.
inline bool cached_default_scan(std::string *ret_dir)
{
	const char *cache = std::getenv("FACESCAN_TEST_CACHE");
	if (!cache || !*cache)
		return false;
	const std::string dir = std::string(cache) + "/default-scan";
	std::error_code ec;
	if (!std::filesystem::is_directory(dir, ec))
		return false;
	*ret_dir = dir;
	return true;
}

/// Leaves `scan` (simulate_default_scan's) for the other tests of this run, unless one already
/// did: written into a temporary directory, then renamed into place whole.
inline void cache_default_scan(const SimulatedScan &scan)
{
	std::string dir;
	const char *cache = std::getenv("FACESCAN_TEST_CACHE");
	if (!cache || !*cache || cached_default_scan(&dir))
		return;
	const std::string tmp = std::string(cache) + "/default-scan.tmp" + std::to_string(getpid());
	std::error_code ec;
	if (sim::write_simulated_set(tmp, scan.set, scan.sim_truth).ok())
		std::filesystem::rename(tmp, std::string(cache) + "/default-scan", ec);
	std::filesystem::remove_all(tmp, ec);
}

} // namespace facescan::testing
