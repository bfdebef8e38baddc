#include "daemon/sim_renderer.hpp"

namespace facescan::daemon {

Status attach_simulator(const Config &config, const BoothFactory &make_booth, DriverCameras *cameras)
{
	cameras->use_simulator(make_booth, config.sim_scene, config.sim_scale_percent / 100.0, config.spool_dir + "/work");
	return Status();
}

} // namespace facescan::daemon
