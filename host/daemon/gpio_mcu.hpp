// The booth's own GPIO lines around the MCU link (button_source = gpio): the booth button as
// a libgpiod line (debounced by drivers/gpio), the status LED (on while a scan is armed or
// running) and the MCU's reset line (pulsed when the MCU does not answer at open()).
// The loop watches two fds, the link's and the button line's (its kernel event fd, or the
// fake's pipe); while a new level is being held, events_due_ms() says when it settles.
#pragma once

#include "daemon/backends.hpp"

#include <memory>

struct fscan_gpio;
struct fscan_gpio_ops;

namespace facescan::daemon {

class GpioMcu : public Mcu {
public:
	/// Takes over `inner` (the MCU link). `gpio` is an open drivers/gpio handle, owned.
	GpioMcu(std::unique_ptr<Mcu> inner, fscan_gpio *gpio);
	~GpioMcu() override;
	Status open() override;
	void close() override
	{
		inner_->close();
	}
	bool is_open() const override
	{
		return inner_->is_open();
	}
	std::string firmware_version() const override
	{
		return inner_->firmware_version();
	}
	Status arm(const Timing &timing) override;
	Status fire(int timeout_ms, TriggerReport *ret_report) override;
	Status abort() override;
	/// The link's fd (while it is up) and the button line's (until it fails).
	std::vector<int> event_fds() const override;
	/// The sooner of the link's and the debounce's (fscan_gpio_timeout_ms()).
	int events_due_ms() const override;
	Status poll_events(std::vector<McuEvent> *ret_events) override;
	Status simulate_button() override
	{
		return inner_->simulate_button();
	}

private:
	std::unique_ptr<Mcu> inner_;
	fscan_gpio *gpio_;
	bool line_lost_ = false; // the button line failed (its chip went away): no longer watched
};

/// Opens the GPIO lines the config names (libgpiod) and wraps `inner`.
Status make_gpio_mcu(const struct Config &config, std::unique_ptr<Mcu> inner, std::unique_ptr<Mcu> *ret_mcu);

} // namespace facescan::daemon
