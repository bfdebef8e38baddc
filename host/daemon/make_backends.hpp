// Builds the backends a config asks for.
#pragma once

#include "daemon/daemon.hpp"
#include "daemon/driver_cameras.hpp"

namespace facescan::daemon {

/// -ENOTSUP names a backend this build cannot provide. make_booth makes the booth simulator
/// for camera_backend = simulated (the program provides it: the daemon does not include the
/// simulator); empty = none, and the simulated cameras fail to open with -ENOTSUP.
Status make_backends(const Config &config, const BoothFactory &make_booth, Backends *ret_backends);

} // namespace facescan::daemon
