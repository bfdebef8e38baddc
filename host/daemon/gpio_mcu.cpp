#include "daemon/gpio_mcu.hpp"

#include "daemon/config.hpp"
#include "daemon/log.hpp"
#include "facescan/gpio.h"

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace facescan::daemon {

GpioMcu::GpioMcu(std::unique_ptr<Mcu> inner, fscan_gpio *gpio) : inner_(std::move(inner)), gpio_(gpio)
{
}

GpioMcu::~GpioMcu()
{
	fscan_gpio_destroy(gpio_);
}

Status GpioMcu::open()
{
	Status s = inner_->open();
	if (s.ok() || s.code() == -ENOENT || s.code() == -ENODEV)
		return s; // no device at all: a reset will not make one appear
	// The MCU is there but does not answer: reset it once and greet it again.
	if (fscan_gpio_pulse_reset(gpio_, 50) < 0)
		return s;
	Status again = inner_->open();
	return again.ok() ? again : Status::error(again.code(), again.message() + " (also after an MCU reset)");
}

Status GpioMcu::arm(const Timing &timing)
{
	Status s = inner_->arm(timing);
	if (s.ok())
		fscan_gpio_set_led(gpio_, true);
	return s;
}

Status GpioMcu::fire(int timeout_ms, TriggerReport *ret_report)
{
	Status s = inner_->fire(timeout_ms, ret_report);
	fscan_gpio_set_led(gpio_, false);
	return s;
}

Status GpioMcu::abort()
{
	fscan_gpio_set_led(gpio_, false);
	return inner_->abort();
}

std::vector<int> GpioMcu::event_fds() const
{
	std::vector<int> fds = inner_->event_fds();
	int fd = line_lost_ ? -1 : fscan_gpio_fd(gpio_);
	if (fd >= 0)
		fds.push_back(fd);
	return fds;
}

int GpioMcu::events_due_ms() const
{
	int link = inner_->events_due_ms();
	int line = line_lost_ ? -1 : fscan_gpio_timeout_ms(gpio_);
	if (link < 0)
		return line;
	return line < 0 ? link : std::min(link, line);
}

Status GpioMcu::poll_events(std::vector<McuEvent> *ret_events)
{
	Status s = inner_->poll_events(ret_events);
	// The MCU's own button input is not wired in this booth: presses come from the GPIO line.
	for (auto it = ret_events->begin(); it != ret_events->end();)
		it = it->type == McuEvent::Type::button ? ret_events->erase(it) : it + 1;
	while (!line_lost_) {
		fscan_gpio_event ev;
		int rc = fscan_gpio_read_event(gpio_, 0, &ev);
		if (rc == -ETIMEDOUT)
			break;
		if (rc < 0) {
			// A failed line's fd stays readable (POLLERR): watched on, it would spin the loop.
			line_lost_ = true;
			log(LOG_ERR, "GPIO button line: %s; the booth button is off until facescand restarts",
			    std::strerror(-rc));
			break;
		}
		if (ev.type == FSCAN_GPIO_BUTTON_PRESSED)
			ret_events->push_back({McuEvent::Type::button, "gpio"});
	}
	return s;
}

Status make_gpio_mcu(const Config &config, std::unique_ptr<Mcu> inner, std::unique_ptr<Mcu> *ret_mcu)
{
	fscan_gpio_config g{};
	g.chip = config.gpio_chip.c_str();
	g.button_line = static_cast<unsigned>(config.gpio_button_line);
	g.button_active_low = true;
	g.button_pull_up = true;
	g.led_line = static_cast<unsigned>(config.gpio_led_line);
	g.reset_line = static_cast<unsigned>(config.gpio_mcu_reset_line);
	g.reset_active_low = true;
	fscan_gpio *gpio = nullptr;
	int rc = fscan_gpio_create(&fscan_gpio_libgpiod_ops, &g, &gpio);
	if (rc < 0)
		return Status::error(-rc, "gpio " + config.gpio_chip + ": " + std::strerror(-rc));
	*ret_mcu = std::make_unique<GpioMcu>(std::move(inner), gpio);
	return Status();
}

} // namespace facescan::daemon
