#include "daemon/make_backends.hpp"

#include "daemon/driver_cameras.hpp"
#include "daemon/fake_backends.hpp"
#include "daemon/gpio_mcu.hpp"
#include "daemon/pipeline_recon.hpp"
#include "daemon/serial_mcu.hpp"
#include "daemon/sim_renderer.hpp"

namespace facescan::daemon {

Status make_backends(const Config &config, Backends *ret_backends)
{
	Backends b;
	if (config.serial_device == "fake")
		b.mcu = std::make_unique<FakeMcu>();
	else
		b.mcu = std::make_unique<SerialMcu>(config.serial_device, config.serial_baud, config.mode == Mode::booth,
						    config.mcu_timeout_ms);
	if (config.button_source == ButtonSource::gpio) {
		Status s = make_gpio_mcu(config, std::move(b.mcu), &b.mcu);
		if (!s.ok())
			return s;
	}
	if (config.camera_backend == "fake") {
		b.cameras = std::make_unique<FakeCameras>(config.camera_count);
	} else {
		auto cams = std::make_unique<DriverCameras>(config.camera_backend, config.replay_dir, config.camera_count,
							    config.exposure_us, config.max_frame_skew_us);
		if (config.camera_backend == "simulated") {
			Status s = attach_simulator(config, cams.get());
			if (!s.ok())
				return s;
		}
		b.cameras = std::move(cams);
	}
	if (config.recon_backend == "fake") {
		b.recon = std::make_unique<FakeReconstructor>();
	} else {
		if (config.camera_backend == "fake")
			return Status::error(EINVAL, "recon_backend = pipeline cannot reconstruct the fake cameras' "
						     "synthetic frames; use recon_backend = fake with camera_backend = fake");
		b.recon = std::make_unique<PipelineReconstructor>(config.calibration_file, config.pattern_id);
	}
	*ret_backends = std::move(b);
	return Status();
}

} // namespace facescan::daemon
