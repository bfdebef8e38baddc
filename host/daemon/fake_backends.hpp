// Fakes of the booth, for tests and for running facescand where a part is missing. Back doors
// (thread-safe) let tests inject the faults a real booth has: an unplugged MCU, a camera that
// never delivers, frames from a different trigger.
#pragma once

#include "daemon/backends.hpp"

#include <atomic>
#include <memory>
#include <mutex>

namespace facescan::daemon {

class FakeMcu : public Mcu {
public:
	FakeMcu();
	~FakeMcu() override;
	Status open() override;
	void close() override;
	bool is_open() const override;
	std::string firmware_version() const override;
	Status arm(const Timing &timing) override;
	Status fire(int timeout_ms, TriggerReport *ret_report) override;
	Status abort() override;
	int event_fd() const override;
	Status poll_events(std::vector<McuEvent> *ret_events) override;
	Status simulate_button() override;

	// back doors
	void press_button();
	void unplug();         // the link drops now; open() fails until replug()
	void replug();
	void unplug_on_fire(); // the next fire() loses the link mid-sequence
	int fired() const;     // sequences fired so far
	Timing last_timing() const;

private:
	mutable std::mutex mu_;
	int efd_ = -1;
	bool open_ = false;
	bool plugged_ = true;
	bool armed_ = false;
	bool unplug_on_fire_ = false;
	bool lost_ = false;
	int presses_ = 0;
	int fired_ = 0;
	uint32_t sequence_ = 0;
	Timing timing_;
	void kick();
};

class FakeCameras : public Cameras {
public:
	explicit FakeCameras(int count, int width = 64, int height = 48);
	Status open() override;
	std::string backend_name() const override
	{
		return "fake";
	}
	int count() const override
	{
		return count_;
	}
	Status prepare() override;
	Status collect(const TriggerReport &report, int timeout_ms, Capture *ret_capture) override;

	// back doors
	void fail_next_collect_with_timeout(); // one camera never delivers
	void mix_next_trigger();               // one camera delivers a frame of another trigger
	int collected() const
	{
		return collected_;
	}

private:
	int count_, width_, height_;
	std::atomic<bool> timeout_{false};
	std::atomic<bool> mix_{false};
	std::atomic<int> collected_{0};
};

/// A fixed hemisphere (radius 80 mm, about 1.1k vertices), Draco-encoded, textured from
/// camera 0's texture frame (or its pattern frame). Optional delay per run, for fault tests.
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
