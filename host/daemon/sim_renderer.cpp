#include "daemon/sim_renderer.hpp"

namespace facescan::daemon {

Status attach_simulator(const Config &, DriverCameras *)
{
	return Status::error(ENOTSUP, "camera_backend = simulated: the booth simulator's renderer "
				      "(tools/sim render_views/simulate) is not in this build; use "
				      "camera_backend = fake or replay");
}

} // namespace facescan::daemon
