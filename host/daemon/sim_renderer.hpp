// The simulated booth behind the simulated camera backend: renders the scene once per trigger
// pair through tools/sim and hands each camera its frame.
#pragma once

#include "daemon/config.hpp"
#include "daemon/driver_cameras.hpp"

namespace facescan::daemon {

/// Gives `cameras` a renderer drawing config.sim_scene. -ENOTSUP when this build has no
/// simulator renderer.
Status attach_simulator(const Config &config, DriverCameras *cameras);

} // namespace facescan::daemon
