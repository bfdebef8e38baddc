#include "daemon/make_backends.hpp"

#include <cstring>
#include <unistd.h>

#include "daemon/driver_cameras.hpp"
#include "daemon/fake_backends.hpp"
#include "daemon/gpio_mcu.hpp"
#include "daemon/serial_mcu.hpp"
#include "daemon/worker_recon.hpp"
#include "daemon/sim_renderer.hpp"
#include "facescan/serial_fake.h"

namespace facescan::daemon {

Status make_backends(const Config &config, const BoothFactory &make_booth, Backends *ret_backends)
{
	Backends b;
	if (config.serial_device == "fake") {
		// The serial driver's fake transport with the firmware core at its far end: the same
		// SerialMcu, protocol and firmware as a booth, without the cable.
		int rc = fscan_serial_fake_attach_mcu(config.serial_device.c_str());
		if (rc < 0)
			return Status::error(-rc, "fake MCU: " + std::string(std::strerror(-rc)));
		b.mcu = std::make_unique<SerialMcu>(&fscan_serial_fake_ops, config.serial_device,
						    config.mode == Mode::booth, config.mcu_timeout_ms);
	} else {
		b.mcu = std::make_unique<SerialMcu>(config.serial_device, config.serial_baud, config.mode == Mode::booth,
						    config.mcu_timeout_ms);
	}
	if (config.button_source == ButtonSource::gpio) {
		Status s = make_gpio_mcu(config, std::move(b.mcu), &b.mcu);
		if (!s.ok())
			return s;
	}
	auto cams = std::make_unique<DriverCameras>(config.camera_backend, config.replay_dir, config.camera_count,
						    config.exposure_us, config.max_frame_skew_us);
	if (config.camera_backend == "simulated") {
		Status s = attach_simulator(config, make_booth, cams.get());
		if (!s.ok())
			return s;
	}
	b.cameras = std::move(cams);
	if (config.recon_backend == "fake") {
		b.recon = std::make_unique<FakeReconstructor>();
	} else {
		if (config.camera_backend == "fake")
			return Status::error(EINVAL, "recon_backend = pipeline cannot reconstruct the fake cameras' "
						     "synthetic frames; use recon_backend = fake with camera_backend = fake");
		WorkerParams w;
		w.program = config.recon_worker;
		w.calibration_file = config.calibration_file;
		w.pattern_id = config.pattern_id;
		w.spool_dir = config.spool_dir;
		w.timeout_ms = config.recon_timeout_ms;
		w.memory_mb = config.recon_memory_mb;
		w.keep_captures = config.keep_captures;
		if (w.program.empty() || access(w.program.c_str(), X_OK) != 0)
			return Status::error(ENOENT, "recon_worker '" + w.program +
							     "': no program to run the reconstruction in (the facescan CLI)");
		b.recon = std::make_unique<WorkerReconstructor>(w);
	}
	*ret_backends = std::move(b);
	return Status();
}

} // namespace facescan::daemon
