// The reconstruction's fake (recon_backend = fake), for tests and for running facescand without
// the pipeline; a back door fails its next run. The booth's other parts have no fake here: the
// MCU is SerialMcu over the serial driver's fake transport with the firmware core at its far end,
// the cameras DriverCameras over the camera driver's fake backend (make_backends.cpp); their
// faults are injected through facescan/serial_fake.h and facescan/camera_fake.h.
#pragma once

#include "daemon/backends.hpp"

#include <atomic>

namespace facescan::daemon {

/// A fixed hemisphere (radius 80 mm, about 1.1k vertices), Draco-encoded, textured from
/// camera 0's texture frame (or its pattern frame). fail_next_run() fails the next run.
class FakeReconstructor : public Reconstructor {
public:
	std::string backend_name() const override
	{
		return "fake";
	}
	Status run(const Capture &capture, ReconOutput *ret_output) override;
	void fail_next_run();

private:
	std::atomic<bool> fail_{false};
};

/// Encodes an indexed triangle mesh (mm) with Draco (14-bit positions, speed 5).
Status encode_draco(const std::vector<float> &xyz, const std::vector<int> &triangles,
		    std::string *ret_bytes);
/// Decodes Draco bytes; the vertex and face counts, for checks.
Status decode_draco_counts(const std::string &bytes, long *ret_vertices, long *ret_faces);

} // namespace facescan::daemon
