// Builds the backends a config asks for.
#pragma once

#include "daemon/daemon.hpp"

namespace facescan::daemon {

/// -ENOTSUP names a backend this build cannot provide.
Status make_backends(const Config &config, Backends *ret_backends);

} // namespace facescan::daemon
