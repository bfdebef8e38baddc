// The trigger MCU over drivers/serial (the firmware protocol of firmware/protocol/protocol.h).
#pragma once

#include "daemon/backends.hpp"

#include <deque>
#include <memory>
#include <mutex>

struct fscan_serial;
struct fscan_serial_ops;

namespace facescan::daemon {

class SerialMcu : public Mcu {
public:
	/// booth: arm() sends ARM, so a button press starts the sequence in the firmware itself;
	/// clinic: arm() only sets the timing and the host fires.
	SerialMcu(std::string device, int baud, bool booth, int timeout_ms);
	/// Another byte transport: the serial driver's fake (serial_device = fake, tests), whose
	/// device has the firmware core attached (fscan_serial_fake_attach_mcu).
	SerialMcu(const fscan_serial_ops *ops, std::string device, bool booth, int timeout_ms);
	~SerialMcu() override;
	Status open() override;
	void close() override;
	bool is_open() const override;
	std::string firmware_version() const override;
	Status arm(const Timing &timing) override;
	Status fire(int timeout_ms, TriggerReport *ret_report) override;
	Status abort() override;
	/// The serial transport's fd (a tty, or the fake's socket); none while the link is down.
	std::vector<int> event_fds() const override;
	int events_due_ms() const override;
	Status poll_events(std::vector<McuEvent> *ret_events) override;
	Status simulate_button() override;

private:
	const fscan_serial_ops *ops_;
	std::string device_;
	int baud_;
	bool booth_;
	int timeout_ms_;
	mutable std::mutex mu_;
	fscan_serial *link_ = nullptr;
	std::string version_;
	uint32_t tick_hz_ = 0;
	bool button_started_ = false;   // the firmware started a sequence on a press
	bool have_report_ = false;      // its report came while the loop polled events
	std::vector<uint8_t> report_body_;
	Status link_error(int rc, const std::string &what);
	Status report_from_frame(const void *frame, TriggerReport *ret);
};

} // namespace facescan::daemon
