#include "daemon/serial_mcu.hpp"

#include "facescan/serial.h"

#include <chrono>
#include <cstring>

namespace facescan::daemon {

SerialMcu::SerialMcu(std::string device, int baud, bool booth, int timeout_ms)
	: ops_(&fscan_serial_termios_ops), device_(std::move(device)), baud_(baud), booth_(booth), timeout_ms_(timeout_ms)
{
}

SerialMcu::SerialMcu(const fscan_serial_ops *ops, std::string device, bool booth, int timeout_ms)
	: ops_(ops), device_(std::move(device)), baud_(115200), booth_(booth), timeout_ms_(timeout_ms)
{
}

SerialMcu::~SerialMcu()
{
	fscan_serial_destroy(link_);
}

// Words for the operator, not errno's ("Transport endpoint is not connected").
static std::string link_words(int rc, int timeout_ms)
{
	if (rc == -ENOTCONN)
		return "link lost (MCU unplugged, off or restarting)";
	if (rc == -EIO)
		return "link lost (I/O error)";
	if (rc == -ETIMEDOUT)
		return "no answer within " + std::to_string(timeout_ms) + " ms";
	return std::strerror(-rc);
}

Status SerialMcu::link_error(int rc, const std::string &what)
{
	if (rc == -ENOTCONN || rc == -EIO) {
		fscan_serial_destroy(link_);
		link_ = nullptr;
	}
	std::string why = rc == -EREMOTEIO ? std::string("refused: ") + fs_err_name(fscan_serial_last_nack(link_))
					   : link_words(rc, timeout_ms_);
	return Status::error(-rc, "MCU " + what + ": " + why);
}

Status SerialMcu::open()
{
	std::lock_guard<std::mutex> lock(mu_);
	if (link_)
		return Status();
	fscan_serial_config cfg = {device_.c_str(), static_cast<unsigned>(baud_)};
	int rc = fscan_serial_create(ops_, &cfg, &link_);
	if (rc < 0) {
		link_ = nullptr;
		return Status::error(-rc, device_ + ": " + std::strerror(-rc));
	}
	fscan_serial_flush_input(link_);
	fs_hello hello;
	rc = fscan_serial_hello(link_, &hello, timeout_ms_);
	if (rc < 0) {
		Status s = link_error(rc, "hello");
		fscan_serial_destroy(link_);
		link_ = nullptr;
		return s;
	}
	if (hello.proto_version != FS_PROTO_VERSION) {
		fscan_serial_destroy(link_);
		link_ = nullptr;
		return Status::error(EPROTO, "MCU speaks protocol " + std::to_string(hello.proto_version) +
						     ", we speak " + std::to_string(FS_PROTO_VERSION));
	}
	tick_hz_ = hello.tick_hz;
	static const char *boards[] = {"?", "native", "lm3s6965evb", "stm32f103"};
	version_ = "firmware " + std::to_string(hello.fw_major) + "." + std::to_string(hello.fw_minor) + " on " +
		   (hello.board < 4 ? boards[hello.board] : "?") + ", protocol " + std::to_string(hello.proto_version);
	fs_status st;
	rc = fscan_serial_status(link_, &st, timeout_ms_);
	if (rc == 0 && st.state == FS_STATE_FAULT)
		rc = fscan_serial_command(link_, FS_CMD_CLEAR_FAULT, timeout_ms_);
	if (rc == 0 && st.state == FS_STATE_ARMED)
		rc = fscan_serial_command(link_, FS_CMD_DISARM, timeout_ms_);
	if (rc < 0) {
		Status s = link_error(rc, "status");
		fscan_serial_destroy(link_);
		link_ = nullptr;
		return s;
	}
	button_started_ = have_report_ = false;
	return Status();
}

void SerialMcu::close()
{
	std::lock_guard<std::mutex> lock(mu_);
	fscan_serial_destroy(link_);
	link_ = nullptr;
}

bool SerialMcu::is_open() const
{
	std::lock_guard<std::mutex> lock(mu_);
	return link_ != nullptr;
}

std::string SerialMcu::firmware_version() const
{
	std::lock_guard<std::mutex> lock(mu_);
	return version_;
}

Status SerialMcu::arm(const Timing &timing)
{
	std::lock_guard<std::mutex> lock(mu_);
	if (!link_)
		return Status::error(ENOTCONN, "MCU link is down");
	fs_timing t;
	fs_timing_default(&t);
	t.proj_settle_us = static_cast<uint32_t>(timing.projector_settle_us);
	t.exposure_us = static_cast<uint32_t>(timing.exposure_us);
	t.flash_exposure_us = static_cast<uint32_t>(timing.texture_exposure_us);
	if (fs_timing_validate(&t) < 0)
		return Status::error(ERANGE, "timing outside the firmware's bounds (see protocol.h FS_TIMING_*)");
	int rc = fscan_serial_set_timing(link_, &t, timeout_ms_);
	if (rc < 0)
		return link_error(rc, "set timing");
	button_started_ = have_report_ = false;
	if (booth_) {
		rc = fscan_serial_command(link_, FS_CMD_ARM, timeout_ms_);
		if (rc < 0)
			return link_error(rc, "arm");
	}
	return Status();
}

Status SerialMcu::report_from_frame(const void *frame, TriggerReport *ret)
{
	fs_report r;
	if (fs_report_get(static_cast<const fs_frame *>(frame), &r) < 0)
		return Status::error(EPROTO, "MCU sent a malformed report");
	if (r.lines_end & FS_LINES_LIGHT)
		return Status::error(EPROTO, "MCU report: lights still on after the sequence");
	if (r.result != FS_REPORT_DONE)
		return Status::error(EIO, std::string("MCU sequence ") + (r.result == FS_REPORT_ABORTED ? "aborted" : "faulted") +
						  " after " + std::to_string(r.steps) + " steps");
	TriggerReport t;
	t.sequence = r.scan;
	t.tick_hz = tick_hz_;
	nlohmann::json ticks = nlohmann::json::array(), lines = nlohmann::json::array();
	for (int i = 0; i < r.steps && i < FS_STEP__COUNT; i++) {
		ticks.push_back(r.tick[i]);
		lines.push_back(r.lines[i]);
	}
	// All four shutters rise in one port write, so each frame kind has one edge tick.
	for (int i = 0; i < 4; i++)
		t.edge_ticks.push_back(r.tick[FS_STEP_SHUT1_RISE]);
	for (int i = 0; i < 4; i++)
		t.edge_ticks.push_back(r.tick[FS_STEP_SHUT2_RISE]);
	bool lockstep = (r.lines[FS_STEP_SHUT1_RISE] & FS_LINES_SHUT) == FS_LINES_SHUT &&
			(r.lines[FS_STEP_SHUT2_RISE] & FS_LINES_SHUT) == FS_LINES_SHUT;
	t.raw = {{"scan", r.scan},
		 {"trigger", r.trigger == FS_TRIGGER_BUTTON ? "button" : "host"},
		 {"tick_hz", tick_hz_},
		 {"steps", r.steps},
		 {"step_ticks", ticks},
		 {"step_lines", lines},
		 {"lines_end", r.lines_end},
		 {"shutters_in_lockstep", lockstep},
		 {"pattern_exposure_ticks", r.tick[FS_STEP_SHUT1_FALL] - r.tick[FS_STEP_SHUT1_RISE]},
		 {"texture_exposure_ticks", r.tick[FS_STEP_SHUT2_FALL] - r.tick[FS_STEP_SHUT2_RISE]},
		 {"firmware", version_}};
	*ret = std::move(t);
	return Status();
}

Status SerialMcu::fire(int timeout_ms, TriggerReport *ret_report)
{
	std::lock_guard<std::mutex> lock(mu_);
	if (!link_)
		return Status::error(ENOTCONN, "MCU link is down");
	if (have_report_) {
		have_report_ = button_started_ = false;
		fs_frame f;
		fs_frame_init(&f, FS_EVT_REPORT, 0);
		f.len = static_cast<uint8_t>(report_body_.size());
		std::memcpy(f.body, report_body_.data(), report_body_.size());
		return report_from_frame(&f, ret_report);
	}
	if (!button_started_) {
		int rc = fscan_serial_command(link_, FS_CMD_FIRE, timeout_ms_);
		if (rc < 0)
			return link_error(rc, "fire");
	}
	button_started_ = false;
	// The sequence itself takes tens of ms; the report must follow within the timeout.
	auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
	for (;;) {
		int left = static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(
							deadline - std::chrono::steady_clock::now())
							.count());
		if (left <= 0)
			return Status::error(ETIMEDOUT, "MCU: no sequence report within " + std::to_string(timeout_ms) + " ms");
		fs_frame ev;
		int rc = fscan_serial_next_event(link_, &ev, left);
		if (rc == -ETIMEDOUT)
			continue;
		if (rc < 0)
			return link_error(rc, "waiting for the report");
		if (ev.type == FS_EVT_REPORT)
			return report_from_frame(&ev, ret_report);
		if (ev.type == FS_EVT_FAULT)
			return Status::error(EIO, "MCU fault during the sequence (lights forced off)");
		if (ev.type == FS_EVT_BOOT)
			return Status::error(EIO, "MCU reset during the sequence");
	}
}

Status SerialMcu::abort()
{
	std::lock_guard<std::mutex> lock(mu_);
	button_started_ = have_report_ = false;
	if (!link_)
		return Status();
	int rc = fscan_serial_command(link_, FS_CMD_ABORT, timeout_ms_);
	if (rc == 0 && booth_)
		rc = fscan_serial_command(link_, FS_CMD_DISARM, timeout_ms_);
	return rc < 0 ? link_error(rc, "abort") : Status();
}

std::vector<int> SerialMcu::event_fds() const
{
	std::lock_guard<std::mutex> lock(mu_);
	int fd = link_ ? fscan_serial_fd(link_) : -1;
	if (fd < 0)
		return {};
	return {fd};
}

int SerialMcu::events_due_ms() const
{
	std::lock_guard<std::mutex> lock(mu_);
	return link_ && fscan_serial_pending(link_) ? 0 : -1;
}

Status SerialMcu::poll_events(std::vector<McuEvent> *ret_events)
{
	std::lock_guard<std::mutex> lock(mu_);
	ret_events->clear();
	if (!link_)
		return Status();
	for (;;) {
		fs_frame ev;
		int rc = fscan_serial_next_event(link_, &ev, 0);
		if (rc == -ETIMEDOUT)
			return Status();
		if (rc < 0) {
			fscan_serial_destroy(link_);
			link_ = nullptr;
			ret_events->push_back({McuEvent::Type::disconnected, link_words(rc, timeout_ms_)});
			return Status();
		}
		switch (ev.type) {
		case FS_EVT_BUTTON: {
			fs_button b;
			if (fs_button_get(&ev, &b) == 0 && b.started)
				button_started_ = true;
			ret_events->push_back({McuEvent::Type::button, b.started ? "started" : ""});
			break;
		}
		case FS_EVT_REPORT:
			if (button_started_) {
				have_report_ = true;
				report_body_.assign(ev.body, ev.body + ev.len);
			}
			break;
		case FS_EVT_FAULT:
			ret_events->push_back({McuEvent::Type::fault, "lights forced off"});
			fscan_serial_command(link_, FS_CMD_CLEAR_FAULT, timeout_ms_);
			break;
		case FS_EVT_BOOT:
			// The MCU reset under us: greet it again on the next recovery.
			fscan_serial_destroy(link_);
			link_ = nullptr;
			ret_events->push_back({McuEvent::Type::disconnected, "MCU reset"});
			return Status();
		default:
			break;
		}
	}
}

Status SerialMcu::simulate_button()
{
	std::lock_guard<std::mutex> lock(mu_);
	if (!link_)
		return Status::error(ENOTCONN, "MCU link is down");
	fs_frame f;
	fs_frame_init(&f, FS_CMD_DEBUG_BUTTON, 0);
	fs_debug_button_put(&f, 60);
	int rc = fscan_serial_request(link_, &f, nullptr, timeout_ms_);
	if (rc == -EREMOTEIO)
		return Status::error(ENOTSUP, "this MCU board has no simulated button");
	return rc < 0 ? link_error(rc, "debug button") : Status();
}

} // namespace facescan::daemon
