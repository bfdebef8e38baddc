// The booth simulator (tools/sim, sim/booth_camera.h) as the daemon's SimulatedBooth: what
// facescand injects for camera_backend = simulated, so that host/daemon includes no simulator.
#pragma once

#include "daemon/driver_cameras.hpp"

namespace facescan::facescand {

/// A daemon::BoothFactory once faults_path is bound: the default rig at `scale`, scene `scene`,
/// this build's default pattern, noise seed 1 for the first scan. faults_path (config
/// sim_camera_faults; empty: none) is read at each scan: "drop CAMERA" (its frames never come)
/// or "delay CAMERA MS" (they come MS after the arm). -EINVAL unknown scene or bad scale.
Status make_sim_booth(const std::string &scene, double scale, const std::string &faults_path,
		      std::unique_ptr<daemon::SimulatedBooth> *ret_booth);

} // namespace facescan::facescand
