#include "daemon/driver_cameras.hpp"

#include "capture/capture_set.hpp"
#include "facescan/camera.h"

#include <opencv2/imgproc.hpp>

#include <cstring>
#include <sys/stat.h>

namespace facescan::daemon {

DriverCameras::DriverCameras(std::string backend, std::string source, int count, int exposure_us, int max_skew_us)
	: backend_(std::move(backend)), source_(std::move(source)), count_(count), exposure_us_(exposure_us),
	  max_skew_us_(max_skew_us)
{
}

DriverCameras::~DriverCameras()
{
	fscan_camera_destroy(cam_);
}

void DriverCameras::use_simulator(BoothFactory make_booth, std::string scene, double scale, std::string work_dir)
{
	make_booth_ = std::move(make_booth);
	sim_scene_ = std::move(scene);
	sim_scale_ = scale;
	work_dir_ = std::move(work_dir);
}

Status DriverCameras::open()
{
	fscan_camera_destroy(cam_);
	cam_ = nullptr;
	const fscan_camera_ops *ops = nullptr;
	fscan_camera_params p{};
	p.count = static_cast<uint32_t>(count_);
	if (backend_ == "libcamera") {
		// In a child process: libcamera 0.0.3 aborts its process when a camera vanishes
		// mid-stream; the daemon must report the camera failed and live on.
		ops = &fscan_camera_isolated_ops;
		p.isolated_inner = &fscan_camera_libcamera_ops;
	} else if (backend_ == "replay") {
		ops = &fscan_camera_replay_ops;
		p.source = source_.c_str();
	} else if (backend_ == "simulated" && make_booth_ && !sim_scene_.empty()) {
		ops = &fscan_camera_sim_ops;
		if (!booth_) {
			Status s = make_booth_(sim_scene_, sim_scale_, &booth_);
			if (!s.ok()) {
				booth_.reset();
				return Status::error(s.code(), "booth simulator: " + s.message());
			}
		}
		Status s = booth_->camera_params(&p);
		if (!s.ok())
			return Status::error(s.code(), "booth simulator: " + s.message());
		calibration_id_ = "simulated rig, scene " + sim_scene_;
	} else if (backend_ == "simulated") {
		return Status::error(ENOTSUP, "simulated cameras: no booth simulator in this program");
	} else if (backend_ == "fake") {
		ops = &fscan_camera_fake_ops;
		calibration_id_ = "fake-calibration";
	} else {
		return Status::error(EINVAL, "unknown camera backend " + backend_);
	}
	int rc = fscan_camera_create(ops, &p, &cam_);
	if (rc < 0) {
		cam_ = nullptr;
		return Status::error(-rc, backend_ + " cameras: " + std::strerror(-rc));
	}
	if (fscan_camera_count(cam_) != count_) {
		int n = fscan_camera_count(cam_);
		fscan_camera_destroy(cam_);
		cam_ = nullptr;
		return Status::error(ENODEV, backend_ + " cameras: found " + std::to_string(n) + ", configured " +
						     std::to_string(count_));
	}
	fscan_camera_config cfg{};
	cfg.exposure_us = static_cast<uint32_t>(exposure_us_);
	cfg.max_skew_us = static_cast<uint32_t>(max_skew_us_ > 0 ? max_skew_us_ : 1);
	cfg.external_trigger = true;
	rc = fscan_camera_configure(cam_, &cfg);
	if (rc < 0)
		return Status::error(-rc, backend_ + " cameras: configure: " + std::strerror(-rc));
	if (backend_ == "replay") {
		Calibration cal;
		if (read_calibration(source_ + "/calibration.yaml", &cal).ok())
			calibration_id_ = cal.id.empty() ? "replay:" + source_ : cal.id;
	}
	return Status();
}

int DriverCameras::count() const
{
	return count_;
}

Status DriverCameras::prepare()
{
	if (!cam_)
		return Status::error(ENODEV, "cameras are not open");
	fscan_camera_disarm(cam_);
	// Trigger 0 = pattern shot, 1 = texture shot (capture format). A replay set without
	// textures has only the first.
	shots_ = 2;
	int rc = fscan_camera_arm(cam_, 0, shots_);
	if (rc == -ENODATA) {
		shots_ = 1;
		rc = fscan_camera_arm(cam_, 0, shots_);
	}
	if (rc < 0)
		return Status::error(-rc, "cameras: arm: " + std::string(std::strerror(-rc)));
	return Status();
}

Status DriverCameras::collect(const TriggerReport &report, int timeout_ms, Capture *ret_capture)
{
	Capture c;
	c.report = report;
	c.calibration_id = calibration_id_;
	c.source_dir = backend_ == "replay" ? source_ : "";
	for (uint32_t shot = 0; shot < shots_; shot++) {
		fscan_frame_set *set = nullptr;
		int rc = fscan_camera_collect(cam_, timeout_ms, &set);
		if (rc < 0) {
			std::string which;
			for (int i = 0; i < count_; i++) {
				int st = fscan_camera_frame_status(cam_, static_cast<uint32_t>(i));
				if (st < 0)
					which += std::string(which.empty() ? "" : "; ") + "camera " + std::to_string(i) + ": " +
						 (st == -ETIMEDOUT ? "no frame"
						  : st == -EIO    ? "failed frame"
						  : st == -EXDEV  ? "frame of another trigger or too late"
								  : std::strerror(-st));
			}
			fscan_camera_disarm(cam_);
			std::string what = rc == -EXDEV ? "frames from different triggers or too far apart"
				       : rc == -ETIMEDOUT ? "no frame within " + std::to_string(timeout_ms) + " ms"
							  : std::strerror(-rc);
			return Status::error(rc == -EXDEV ? EPROTO : -rc, what + (which.empty() ? "" : " (" + which + ")"));
		}
		for (uint32_t i = 0; i < set->count; i++) {
			const fscan_frame &f = set->frames[i];
			Frame fr;
			fr.camera = static_cast<int>(f.camera);
			fr.texture = shot == 1;
			// The driver has checked that the set is one trigger; the trigger is the MCU's.
			fr.trigger = f.trigger_seq == shot ? report.sequence : f.trigger_seq + 1000000;
			fr.timestamp_ns = static_cast<int64_t>(f.timestamp_ns);
			cv::Mat rgb(static_cast<int>(f.height), static_cast<int>(f.width), CV_8UC3, f.data, f.stride);
			cv::cvtColor(rgb, fr.image, cv::COLOR_RGB2BGR);
			c.frames.push_back(std::move(fr));
		}
		fscan_frame_set_free(set);
	}
	c.meta = {{"backend", backend_}, {"shots", shots_}};
	if (booth_) {
		// The scan as a capture set (calibration, frames, ground truth) for the reconstruction.
		const std::string dir = work_dir_ + "/simulated-capture";
		::mkdir(work_dir_.c_str(), 0750);
		Status s = booth_->write_last(dir);
		if (!s.ok())
			return Status::error(s.code(), "booth simulator: " + s.message());
		c.source_dir = dir;
		c.meta["scene"] = sim_scene_;
	}
	*ret_capture = std::move(c);
	return Status();
}

} // namespace facescan::daemon
