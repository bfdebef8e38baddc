// The booth cameras over drivers/camera (libcamera, replay, simulated or the driver's fake).
#pragma once

#include "daemon/backends.hpp"

#include <functional>
#include <memory>

struct fscan_camera;
struct fscan_camera_ops;
struct fscan_camera_params;

namespace facescan::daemon {

/// The booth simulator behind camera_backend "simulated". The program that opens the cameras
/// makes it (facescand: host/facescand/sim_booth.hpp, over tools/sim); the daemon does not
/// include the simulator (docs/architecture.md, "Layers").
class SimulatedBooth {
public:
	virtual ~SimulatedBooth() = default;
	/// Count, sensor size, render callback and its context for fscan_camera_sim_ops. The
	/// booth outlives the camera opened with them.
	virtual Status camera_params(fscan_camera_params *ret_params) = 0;
	/// Writes the last rendered scan as a capture set with ground truth into dir.
	virtual Status write_last(const std::string &dir) = 0;
};

/// Makes the booth rendering `scene` at camera resolution `scale` (0 = the rig's).
using BoothFactory =
	std::function<Status(const std::string &scene, double scale, std::unique_ptr<SimulatedBooth> *ret_booth)>;

class DriverCameras : public Cameras {
public:
	/// backend: "libcamera", "replay" (source = capture set directory), "simulated" (through
	/// use_simulator()), "fake" (the driver's fake backend: synthetic 64x48 frames, faults
	/// injected through handle() and facescan/camera_fake.h).
	DriverCameras(std::string backend, std::string source, int count, int exposure_us, int max_skew_us);
	~DriverCameras() override;
	/// "simulated" through the booth `make_booth` makes at the first open(): each scan renders
	/// `scene`; the rendered set (with ground truth) is written under work_dir for the
	/// reconstruction.
	void use_simulator(BoothFactory make_booth, std::string scene, double scale, std::string work_dir);
	bool prepare_at_arm() const override
	{
		return backend_ != "simulated"; // the simulator renders at arm: seconds, in the worker
	}
	Status open() override;
	std::string backend_name() const override
	{
		return backend_;
	}
	int count() const override;
	Status prepare() override;
	Status collect(const TriggerReport &report, int timeout_ms, Capture *ret_capture) override;
	/// The driver handle (tests reach the fake's back doors through it).
	fscan_camera *handle()
	{
		return cam_;
	}

private:
	std::string backend_, source_;
	int count_, exposure_us_, max_skew_us_;
	std::string calibration_id_;
	fscan_camera *cam_ = nullptr;
	BoothFactory make_booth_;
	std::unique_ptr<SimulatedBooth> booth_; // outlives cam_ (~DriverCameras destroys cam_ first)
	std::string sim_scene_, work_dir_;
	double sim_scale_ = 0;
	uint32_t shots_ = 2;
};

} // namespace facescan::daemon
