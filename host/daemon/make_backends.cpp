#include "daemon/make_backends.hpp"

#include "daemon/fake_backends.hpp"

namespace facescan::daemon {

Status make_backends(const Config &config, Backends *ret_backends)
{
	Backends b;
	if (config.serial_device == "fake")
		b.mcu = std::make_unique<FakeMcu>();
	else
		return Status::error(ENOTSUP, "serial_device: the serial MCU backend is not in this build; "
					      "use serial_device = fake");
	if (config.camera_backend == "fake")
		b.cameras = std::make_unique<FakeCameras>(config.camera_count);
	else
		return Status::error(ENOTSUP, "camera_backend = " + config.camera_backend +
						      " is not in this build; use camera_backend = fake");
	if (config.recon_backend == "fake")
		b.recon = std::make_unique<FakeReconstructor>();
	else
		return Status::error(ENOTSUP, "recon_backend = " + config.recon_backend +
						      " is not in this build; use recon_backend = fake");
	*ret_backends = std::move(b);
	return Status();
}

} // namespace facescan::daemon
