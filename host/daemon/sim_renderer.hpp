// The simulated booth behind the simulated camera backend: renders the scene once per trigger
// pair through the booth the program injects (facescand: tools/sim) and hands each camera its
// frame.
#pragma once

#include "daemon/config.hpp"
#include "daemon/driver_cameras.hpp"

namespace facescan::daemon {

/// Gives `cameras` the booth `make_booth` makes, drawing config.sim_scene. Without one (an
/// empty factory) opening the cameras fails with -ENOTSUP.
Status attach_simulator(const Config &config, const BoothFactory &make_booth, DriverCameras *cameras);

} // namespace facescan::daemon
