// The hardware and pipeline facescand drives, as C++ interfaces, each with an adapter over the
// real part (drivers/, host/recon). The fakes sit below the adapters, beside the real parts: the
// serial driver's fake transport with the firmware core at its far end, the camera driver's
// fake backend (back doors for fault tests in facescan/*_fake.h); only the reconstruction has a
// fake of its own here (fake_backends.hpp). The daemon holds them; only the thread that
// owns the booth's current stage calls them (see daemon.hpp).
#pragma once

#include "common/status.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace facescan::daemon {

/// Firmware timing sent at every arm (µs).
struct Timing {
	int projector_settle_us = 0;
	int exposure_us = 0;
	int texture_exposure_us = 0;
};

/// What the MCU says it did for one fired sequence.
struct TriggerReport {
	uint32_t sequence = 0;           // the firmware's trigger counter
	uint32_t tick_hz = 0;            // timer frequency of the edge timestamps
	std::vector<uint64_t> edge_ticks; // shutter edges (pattern frames then texture frames)
	nlohmann::json raw;              // everything the firmware reported, for the metadata
};

struct McuEvent {
	enum class Type { button, fault, disconnected } type;
	std::string detail;
};

/// The trigger controller (firmware over serial, or a fake).
class Mcu {
public:
	virtual ~Mcu() = default;
	/// Opens the link and performs the version handshake. -ENODEV / -EIO / -ETIMEDOUT / -EPROTO.
	virtual Status open() = 0;
	virtual void close() = 0;
	virtual bool is_open() const = 0;
	virtual std::string firmware_version() const = 0;
	/// Sends the timing and arms the sequence.
	virtual Status arm(const Timing &timing) = 0;
	/// Fires the armed sequence and waits for its report. -ETIMEDOUT, -EIO (link lost).
	virtual Status fire(int timeout_ms, TriggerReport *ret_report) = 0;
	/// Aborts an armed or running sequence (lights off). Best effort.
	virtual Status abort() = 0;
	/// The file descriptors the loop watches: one becomes readable when events may be pending
	/// (the link's, a GPIO line's). Nothing is polled on a timer: a backend with events has an
	/// fd for them. Without the link (down, or not open) its fd is missing. They may change
	/// across open(); the loop asks again before each poll().
	virtual std::vector<int> event_fds() const = 0;
	/// When the loop must collect events although no fd woke it: -1 not; 0 now (events the
	/// backend read while a command waited for its answer); N > 0 within N ms (a GPIO level
	/// being debounced settles then).
	virtual int events_due_ms() const
	{
		return -1;
	}
	/// Collects pending events without blocking. A lost link shows as a `disconnected` event.
	virtual Status poll_events(std::vector<McuEvent> *ret_events) = 0;
	/// A simulated button press, where the backend can make one (fake MCU, demo firmware).
	virtual Status simulate_button()
	{
		return Status::error(ENOTSUP, "this MCU backend has no simulated button");
	}
};

struct Frame {
	int camera = 0;
	bool texture = false;  // false: pattern frame, true: texture frame
	uint32_t trigger = 0;  // the trigger sequence this frame belongs to
	int64_t timestamp_ns = 0;
	cv::Mat image;         // 8-bit BGR
};

/// One scan's capture: frames of one trigger from every camera.
struct Capture {
	std::vector<Frame> frames;
	TriggerReport report;
	std::string calibration_id;
	std::string source_dir;  // a capture set on disk (calibration.yaml, cam*.png), if any
	std::string scan_name;   // <UTC time>_<scan-id>: names a capture kept for an offline retry
	nlohmann::json meta;     // backend facts for the metadata
};

/// The booth cameras.
class Cameras {
public:
	virtual ~Cameras() = default;
	virtual Status open() = 0;
	virtual std::string backend_name() const = 0;
	virtual int count() const = 0;
	/// Readies every camera for the next externally triggered frame (before the MCU fires).
	virtual Status prepare() = 0;
	/// Whether prepare() is cheap enough for the daemon's loop at arm time (then requests are
	/// queued before a booth button can fire the sequence). False: the worker prepares.
	virtual bool prepare_at_arm() const
	{
		return true;
	}
	/// Collects the frames of the fired sequence. -ETIMEDOUT if one is missing.
	virtual Status collect(const TriggerReport &report, int timeout_ms, Capture *ret_capture) = 0;
};

struct ReconOutput {
	std::string drc;  // Draco-encoded mesh
	std::string png;  // texture image
	long vertices = 0;
	long faces = 0;
	std::vector<std::pair<std::string, double>> stage_ms; // per pipeline stage
	nlohmann::json quality;                                // quality figures of the run
};

/// Capture set → mesh.
class Reconstructor {
public:
	virtual ~Reconstructor() = default;
	virtual std::string backend_name() const = 0;
	virtual Status run(const Capture &capture, ReconOutput *ret_output) = 0;
	/// The scan named scan_name is committed to the spool: what run() kept of its capture for an
	/// offline retry may go (a failed or interrupted scan keeps it).
	virtual void release(const std::string &scan_name)
	{
		(void)scan_name;
	}
};

/// Checks that a capture holds one pattern and (if any) one texture frame per camera, all from
/// the trigger in the report, with sensor timestamps within max_skew_us per frame kind.
/// -EPROTO names the first camera whose frame does not belong.
Status check_capture(const Capture &capture, int cameras, int max_skew_us);

} // namespace facescan::daemon
