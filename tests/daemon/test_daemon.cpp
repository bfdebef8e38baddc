// facescand in-process with the fake booth (what serial_device / camera_backend / recon_backend
// = fake build: SerialMcu over the serial driver's fake transport with the firmware core at its
// far end, DriverCameras over the camera driver's fake backend, the fake reconstruction): scans
// over the socket and by button, one scan at a time, socket robustness, and the faults (MCU
// unplugged mid-scan, camera timeout, frames from different triggers, a failing
// reconstruction) with recovery. Log lines are captured to check that no patient data reaches
// them.
#include "daemon/clinic_output.hpp"
#include "daemon/client.hpp"
#include "daemon/daemon.hpp"
#include "daemon/driver_cameras.hpp"
#include "daemon/fake_backends.hpp"
#include "daemon/gpio_mcu.hpp"
#include "daemon/make_backends.hpp"
#include "facescan/camera_fake.h"
#include "facescan/gpio.h"
#include "facescan/gpio_fake.h"
#include "facescan/serial_fake.h"
#include "facescan/storage.h"
#include "daemon/log.hpp"

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <grp.h>
#include <mutex>
#include <sstream>
#include <string>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>
#include <thread>
#include <vector>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

using namespace facescan::daemon;
using json = nlohmann::json;

namespace {

std::mutex log_mu;
std::vector<std::string> log_lines;

// The fake booth a config with every backend = fake asks for, as facescand builds it.
Backends fake_booth(const Config &cfg)
{
	Backends b;
	facescan::Status s = make_backends(cfg, BoothFactory(), &b);
	if (!s.ok())
		fail_msg("make_backends: %s", s.message().c_str());
	return b;
}

// The real spool and share, slowed from the test (facescand has no pause of its own to ship):
// the storage driver's posix backend, each scan entry's queue() starting queue_delay_ms late, so
// the daemon stays in `writing` that long. One Rig at a time sets it.
std::atomic<int> queue_delay_ms{0};

int slow_queue(void *ctx, const char *base, const char *scan_id, const char *dir, const fscan_storage_file *files,
	       size_t n_files)
{
	std::this_thread::sleep_for(std::chrono::milliseconds(queue_delay_ms.load()));
	return fscan_storage_posix_ops.queue(ctx, base, scan_id, dir, files, n_files);
}

const fscan_storage_ops slow_posix_ops = [] {
	fscan_storage_ops ops = fscan_storage_posix_ops;
	ops.name = "posix, slow queue";
	ops.queue = slow_queue;
	return ops;
}();

// The back doors of the fake MCU (the firmware core behind the fake serial device).
struct FakeMcuDevice {
	std::string name;
	void press_button()
	{
		assert_int_equal(fscan_serial_fake_mcu_press(name.c_str()), 0);
	}
	void unplug()
	{
		assert_int_equal(fscan_serial_fake_device_unplug(name.c_str()), 0);
	}
	void replug()
	{
		assert_int_equal(fscan_serial_fake_device_plug(name.c_str()), 0);
	}
	void unplug_on_fire()
	{
		assert_int_equal(fscan_serial_fake_mcu_unplug_on_fire(name.c_str()), 0);
	}
	int fired() const
	{
		return fscan_serial_fake_mcu_scans(name.c_str());
	}
};

struct Rig {
	std::string dir;
	Config cfg;
	FakeMcuDevice mcu;
	DriverCameras *cams = nullptr;
	FakeReconstructor *recon = nullptr;
	std::unique_ptr<Daemon> d;
	std::thread loop;

	// queue_delay: how much later than it would each scan's spool write starts (slow_posix_ops)
	explicit Rig(Mode mode = Mode::clinic, int queue_delay = 0, fscan_gpio *gpio = nullptr,
		     int client_timeout_ms = 5000)
	{
		char t[] = "/tmp/facescand-test-XXXXXX";
		assert_non_null(mkdtemp(t));
		dir = t;
		mkdir((dir + "/share").c_str(), 0755);
		cfg.mode = mode;
		cfg.share_dir = dir + "/share";
		cfg.spool_dir = dir + "/spool";
		cfg.socket_path = dir + "/sock";
		cfg.serial_device = "fake";
		cfg.camera_backend = "fake";
		cfg.recon_backend = "fake";
		cfg.min_free_mb = 0;
		cfg.spool_retry_ms = 100;
		cfg.mcu_timeout_ms = 200;
		cfg.capture_timeout_ms = 200;
		cfg.arm_timeout_ms = 1000;
		cfg.client_timeout_ms = client_timeout_ms;
		cfg.camera_count = 4;
		Backends b = fake_booth(cfg);
		mcu.name = cfg.serial_device;
		cams = dynamic_cast<DriverCameras *>(b.cameras.get());
		recon = dynamic_cast<FakeReconstructor *>(b.recon.get());
		assert_non_null(cams);
		assert_non_null(recon);
		if (gpio)
			b.mcu = std::make_unique<GpioMcu>(std::move(b.mcu), gpio);
		queue_delay_ms = queue_delay;
		if (queue_delay > 0)
			b.storage = &slow_posix_ops;
		d = std::make_unique<Daemon>(cfg, std::move(b));
		facescan::Status s = d->start();
		if (!s.ok())
			fail_msg("start: %s", s.message().c_str());
		loop = std::thread([this] { d->run(); });
	}
	~Rig()
	{
		d->request_stop();
		loop.join();
		d.reset();
		queue_delay_ms = 0;
		std::string cmd = "rm -rf '" + dir + "'";
		if (std::system(cmd.c_str()) != 0)
			std::fprintf(stderr, "cannot remove %s\n", dir.c_str());
	}
	json ask(const json &req)
	{
		json reply;
		facescan::Status s = control_request(cfg.socket_path, req,
						     [&](const json &j) {
							     reply = j;
							     return false;
						     },
						     5000);
		if (!s.ok())
			fail_msg("request %s: %s", req.dump().c_str(), s.message().c_str());
		return reply;
	}
	// A scan request followed to its end; returns the final "done" event (or the refusal).
	json scan(const std::string &patient, std::vector<json> *progress = nullptr)
	{
		json last;
		facescan::Status s = control_request(cfg.socket_path, {{"cmd", "scan"}, {"patient", patient}, {"wait", true}},
						     [&](const json &j) {
							     last = j;
							     if (progress)
								     progress->push_back(j);
							     if (j.contains("ok") && !j.contains("event") && !j["ok"].get<bool>())
								     return false;
							     return j.value("event", "") != "done";
						     },
						     10000);
		if (!s.ok())
			fail_msg("scan: %s", s.message().c_str());
		return last;
	}
	bool wait_state(State want, int ms = 5000)
	{
		for (int i = 0; i < ms / 10; i++) {
			if (d->state() == want)
				return true;
			std::this_thread::sleep_for(std::chrono::milliseconds(10));
		}
		return false;
	}
};

// A second daemon on `cfg` with a fake booth of its own (its MCU on another fake serial device:
// the first daemon's link holds "fake"): started, it returns start()'s status.
facescan::Status start_another(const Config &cfg)
{
	Config booth = cfg;
	booth.serial_device = "fake-other";
	booth.camera_backend = "fake";
	booth.recon_backend = "fake";
	Daemon other(cfg, fake_booth(booth));
	return other.start();
}

int connect_to(const std::string &path)
{
	int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	struct sockaddr_un addr = {};
	addr.sun_family = AF_UNIX;
	std::strcpy(addr.sun_path, path.c_str());
	assert_int_equal(connect(fd, reinterpret_cast<sockaddr *>(&addr), sizeof addr), 0);
	return fd;
}

std::string slurp(const std::string &path)
{
	std::ifstream f(path, std::ios::binary);
	std::stringstream ss;
	ss << f.rdbuf();
	return ss.str();
}

int setup(void **)
{
	set_log_sink([](int, const std::string &line) {
		std::lock_guard<std::mutex> lock(log_mu);
		log_lines.push_back(line);
	});
	return 0;
}

int teardown(void **)
{
	set_log_sink(nullptr);
	return 0;
}

void assert_no_log_mentions(const std::string &needle)
{
	std::lock_guard<std::mutex> lock(log_mu);
	for (const std::string &l : log_lines)
		if (l.find(needle) != std::string::npos)
			fail_msg("patient data in the log: %s", l.c_str());
}

} // namespace

static void test_scan_over_socket(void **)
{
	Rig rig;
	std::vector<json> progress;
	json done = rig.scan("PAT-4711", &progress);
	assert_string_equal(done.value("event", "").c_str(), "done");
	assert_true(done["ok"].get<bool>());
	json scan = done["scan"];
	assert_string_equal(scan["state"].get<std::string>().c_str(), "delivered");
	const std::string id = scan["scan_id"];
	assert_int_equal(id.size(), 12);
	// a progress line per stage
	int stages = 0;
	for (const json &p : progress)
		if (p.value("event", "") == "progress")
			stages++;
	assert_true(stages >= 3);
	// <share>/<patient>/<UTC time>_<scan-id>.{drc,png,glb,_thumb.png,json} (glb and thumbnail
	// by default; the metadata last)
	assert_int_equal(scan["files"].size(), 5);
	const std::string drc = scan["files"][0];
	assert_non_null(std::strstr(drc.c_str(), (rig.cfg.share_dir + "/PAT-4711/").c_str()));
	const std::string stem = drc.substr(drc.rfind('/') + 1);
	assert_int_equal(stem.size(), std::string("20260101T000000Z_").size() + 12 + 4);
	assert_true(stem[8] == 'T' && stem[15] == 'Z' && stem.substr(17, 12) == id);
	long v = 0, f = 0;
	assert_true(decode_draco_counts(slurp(drc), &v, &f).ok());
	assert_int_equal(v, scan["vertices"].get<long>());
	assert_int_equal(f, scan["faces"].get<long>());
	assert_true(v > 1000);
	std::string png = slurp(scan["files"][1]);
	assert_true(png.size() > 8 && png.compare(1, 3, "PNG") == 0);
	json meta = json::parse(slurp(scan["files"][4]));
	assert_string_equal(meta["scan_id"].get<std::string>().c_str(), id.c_str());
	// The manifest names every other file with its size and sha256, and they match the share.
	assert_int_equal(meta["manifest"].size(), 4);
	for (const json &m : meta["manifest"]) {
		const std::string body = slurp(rig.cfg.share_dir + "/PAT-4711/" + m["file"].get<std::string>());
		assert_int_equal(body.size(), m["bytes"].get<size_t>());
		assert_string_equal(facescan::daemon::clinic::sha256_hex(body).c_str(), m["sha256"].get<std::string>().c_str());
	}
	const std::string glb = slurp(drc.substr(0, drc.size() - 4) + ".glb");
	assert_true(glb.size() > 12 && glb.compare(0, 4, "glTF") == 0);
	assert_string_equal(meta["patient_id"].get<std::string>().c_str(), "PAT-4711");
	assert_true(meta["stage_ms"].contains("capture") && meta["stage_ms"].contains("reconstruct"));
	assert_int_equal(meta["trigger_report"]["scan"].get<int>(), 1);
	assert_true(meta.contains("software_version") && meta.contains("calibration_id") && meta.contains("quality"));
	// the MCU got the configured timing: the firmware's own shutter pulses (1 MHz ticks) say so
	assert_int_equal(meta["trigger_report"]["pattern_exposure_ticks"].get<int>(), rig.cfg.exposure_us);
	assert_int_equal(meta["trigger_report"]["texture_exposure_ticks"].get<int>(), rig.cfg.texture_exposure_us);
	// status and last
	json st = rig.ask({{"cmd", "status"}});
	assert_string_equal(st["state"].get<std::string>().c_str(), "idle");
	json last = rig.ask({{"cmd", "last"}});
	assert_string_equal(last["last"]["scan_id"].get<std::string>().c_str(), id.c_str());
	assert_no_log_mentions("PAT-4711");
	// the scan id is what the log names
	bool named = false;
	{
		std::lock_guard<std::mutex> lock(log_mu);
		for (const std::string &l : log_lines)
			named = named || l.find(id) != std::string::npos;
	}
	assert_true(named);
}

static void test_socket_mode_and_busy(void **)
{
	Rig rig(Mode::clinic, 300);
	struct stat st;
	assert_int_equal(stat(rig.cfg.socket_path.c_str(), &st), 0);
	assert_true(S_ISSOCK(st.st_mode));
	assert_int_equal(st.st_mode & 0777, 0660);
	json first = rig.ask({{"cmd", "scan"}, {"patient", "A1"}});
	assert_true(first["ok"].get<bool>());
	json second = rig.ask({{"cmd", "scan"}, {"patient", "B2"}});
	assert_false(second["ok"].get<bool>());
	assert_string_equal(second["error"].get<std::string>().c_str(), "busy");
	// a button press during a scan starts nothing either
	rig.mcu.press_button();
	json status = rig.ask({{"cmd", "status"}});
	assert_string_equal(status["scan_id"].get<std::string>().c_str(), first["scan_id"].get<std::string>().c_str());
	assert_true(rig.wait_state(State::idle));
	std::this_thread::sleep_for(std::chrono::milliseconds(200));
	assert_int_equal(rig.mcu.fired(), 1);
	json last = rig.ask({{"cmd", "last"}});
	assert_string_equal(last["last"]["state"].get<std::string>().c_str(), "delivered");
	// the next one is welcome
	json third = rig.scan("C3");
	assert_true(third["ok"].get<bool>());
}

static void test_malformed_and_oversize(void **)
{
	Rig rig;
	std::string reply;
	const char *bad[] = {"not json\n", "{\"cmd\":\"reboot\"}\n", "[]\n", "{\"cmd\":\"scan\",\"patient\":\"../x\"}\n",
			     "\x00\x01\x02\n"};
	const char *codes[] = {"bad_request", "bad_request", "bad_request", "bad_patient_id", "bad_request"};
	for (int i = 0; i < 5; i++) {
		std::string bytes = i == 4 ? std::string("\x00\x01\x02\n", 4) : std::string(bad[i]);
		assert_true(control_raw(rig.cfg.socket_path, bytes, &reply, 2000).ok());
		json j = json::parse(reply);
		assert_false(j["ok"].get<bool>());
		assert_string_equal(j["error"].get<std::string>().c_str(), codes[i]);
	}
	// oversize, with and without a newline at the end
	std::string huge(64 * 1024, 'A');
	assert_true(control_raw(rig.cfg.socket_path, huge, &reply, 2000).ok());
	assert_string_equal(json::parse(reply)["error"].get<std::string>().c_str(), "too_large");
	assert_true(control_raw(rig.cfg.socket_path, "{\"cmd\":\"status\",\"x\":\"" + huge + "\"}\n", &reply, 2000).ok());
	assert_string_equal(json::parse(reply)["error"].get<std::string>().c_str(), "too_large");
	// a client that connects and says nothing does not block others
	int silent = socket(AF_UNIX, SOCK_STREAM, 0);
	struct sockaddr_un addr = {};
	addr.sun_family = AF_UNIX;
	std::strcpy(addr.sun_path, rig.cfg.socket_path.c_str());
	assert_int_equal(connect(silent, reinterpret_cast<sockaddr *>(&addr), sizeof addr), 0);
	// the daemon keeps serving
	json st = rig.ask({{"cmd", "status"}});
	assert_true(st["ok"].get<bool>());
	json done = rig.scan("AFTER-GARBAGE");
	assert_true(done["ok"].get<bool>());
	close(silent);
	// bad patient ids over the socket, one per refused class
	const std::string ids[] = {"", std::string(65, 'x'), "a/b", "a\\b", "a..b", std::string("a\x01" "b"), ".x"};
	for (const std::string &id : ids) {
		json r = rig.ask({{"cmd", "scan"}, {"patient", id}});
		assert_false(r["ok"].get<bool>());
		assert_string_equal(r["error"].get<std::string>().c_str(), "bad_patient_id");
	}
	assert_int_equal(rig.mcu.fired(), 1);
}

static void test_booth_button(void **)
{
	Rig rig(Mode::booth);
	// a press with nothing armed: a walk-in scan
	rig.mcu.press_button();
	assert_true(rig.wait_state(State::capturing, 2000) || rig.mcu.fired() == 1);
	assert_true(rig.wait_state(State::idle));
	json last = rig.ask({{"cmd", "last"}});
	assert_string_equal(last["last"]["patient_id"].get<std::string>().c_str(), "walk-in");
	assert_string_equal(last["last"]["state"].get<std::string>().c_str(), "delivered");
	// a request arms; the press fires it
	json armed = rig.ask({{"cmd", "scan"}, {"patient", "BOOTH-7"}});
	assert_string_equal(armed["state"].get<std::string>().c_str(), "armed");
	assert_int_equal(static_cast<int>(rig.d->state()), static_cast<int>(State::armed));
	json again = rig.ask({{"cmd", "scan"}, {"patient", "OTHER"}});
	assert_string_equal(again["error"].get<std::string>().c_str(), "busy");
	assert_true(rig.ask({{"cmd", "button"}})["ok"].get<bool>()); // the simulated button
	assert_true(rig.wait_state(State::idle));
	std::this_thread::sleep_for(std::chrono::milliseconds(100));
	last = rig.ask({{"cmd", "last"}});
	assert_string_equal(last["last"]["patient_id"].get<std::string>().c_str(), "BOOTH-7");
	assert_int_equal(rig.mcu.fired(), 2);
	// armed then cancelled; armed then timed out
	rig.ask({{"cmd", "scan"}, {"patient", "CANCEL-ME"}});
	assert_true(rig.ask({{"cmd", "cancel"}})["ok"].get<bool>());
	assert_int_equal(static_cast<int>(rig.d->state()), static_cast<int>(State::idle));
	rig.ask({{"cmd", "scan"}, {"patient", "TOO-SLOW"}});
	std::this_thread::sleep_for(std::chrono::milliseconds(1300));
	assert_int_equal(static_cast<int>(rig.d->state()), static_cast<int>(State::idle));
	assert_string_equal(rig.ask({{"cmd", "last"}})["last"]["state"].get<std::string>().c_str(), "cancelled");
	assert_int_equal(rig.mcu.fired(), 2);
	assert_no_log_mentions("BOOTH-7");
}

// The booth's lines on the gpio driver's fake chip.
static fscan_gpio_config fake_gpio_lines()
{
	fscan_gpio_config g{};
	g.chip = "fake";
	g.button_line = 3;
	g.led_line = 4;
	g.reset_line = 5;
	return g;
}

// GpioMcu gives the loop the button line's fd beside the link's, and the debounce's deadline:
// nothing is polled on a timer, so an edge that left the fd quiet would never be seen. The fake
// line's fd is its pipe; the real line's is libgpiod's event fd, the same contract on gpio-sim
// (tests/vm/test_vm_gpio.c, test_fd_wakes_on_an_edge).
static void test_gpio_mcu_watched_not_polled(void **)
{
	fscan_gpio_config g = fake_gpio_lines();
	g.debounce_ms = 1000; // wide, so that a slow machine cannot let the hold pass unseen
	fscan_gpio *gpio = nullptr;
	assert_int_equal(fscan_gpio_create(&fscan_gpio_fake_ops, &g, &gpio), 0);
	Config cfg;
	cfg.serial_device = "fake";
	cfg.camera_backend = "fake";
	cfg.recon_backend = "fake";
	GpioMcu m(std::move(fake_booth(cfg).mcu), gpio);
	auto readable = [&m](int timeout_ms) {
		std::vector<pollfd> p;
		for (int fd : m.event_fds())
			p.push_back({fd, POLLIN, 0});
		return poll(p.data(), p.size(), timeout_ms) > 0;
	};
	// link down: only the line is watched; up: both
	assert_int_equal(m.event_fds().size(), 1);
	assert_true(m.open().ok());
	assert_int_equal(m.event_fds().size(), 2);
	assert_false(readable(0));
	assert_int_equal(m.events_due_ms(), -1);
	// an edge wakes the loop at once
	assert_int_equal(fscan_gpio_fake_button(gpio, true), 0);
	assert_true(readable(200));
	std::vector<McuEvent> ev;
	assert_true(m.poll_events(&ev).ok());
	assert_true(ev.empty()); // not held for the window yet
	assert_false(readable(0));
	int due = m.events_due_ms();
	std::printf("  press held, settles in %d ms\n", due);
	assert_in_range(due, 1, 1000);
	// held for the window: due now, and one press
	assert_int_equal(fscan_gpio_fake_advance_ns(gpio, 1100000000), 0);
	assert_int_equal(m.events_due_ms(), 0);
	assert_true(m.poll_events(&ev).ok());
	assert_int_equal(ev.size(), 1);
	assert_true(ev[0].type == McuEvent::Type::button);
	assert_int_equal(m.events_due_ms(), -1);
	// a line that fails (its chip gone) is watched no more: its fd would stay readable
	assert_int_equal(fscan_gpio_fake_fail_next(gpio, "read_edge", -ENODEV), 0);
	assert_true(m.poll_events(&ev).ok());
	assert_true(ev.empty());
	assert_int_equal(m.event_fds().size(), 1);
	assert_int_equal(m.events_due_ms(), -1);
	m.close();
}

static void test_gpio_button_and_led(void **)
{
	fscan_gpio_config g = fake_gpio_lines();
	fscan_gpio *gpio = nullptr;
	assert_int_equal(fscan_gpio_create(&fscan_gpio_fake_ops, &g, &gpio), 0);
	Rig rig(Mode::booth, 0, gpio);
	// The MCU's own button input is ignored when the booth button is a GPIO line.
	rig.mcu.press_button();
	std::this_thread::sleep_for(std::chrono::milliseconds(200));
	assert_int_equal(rig.mcu.fired(), 0);
	json armed = rig.ask({{"cmd", "scan"}, {"patient", "GPIO-1"}});
	assert_string_equal(armed["state"].get<std::string>().c_str(), "armed");
	assert_int_equal(fscan_gpio_fake_output(gpio, FSCAN_GPIO_LED), 1); // LED on while armed
	// A glitch shorter than the debounce window (20 ms) starts nothing; a held press does.
	assert_int_equal(fscan_gpio_fake_button(gpio, true), 0);
	assert_int_equal(fscan_gpio_fake_button(gpio, false), 0);
	std::this_thread::sleep_for(std::chrono::milliseconds(200));
	assert_int_equal(rig.mcu.fired(), 0);
	assert_int_equal(fscan_gpio_fake_button(gpio, true), 0);
	std::this_thread::sleep_for(std::chrono::milliseconds(60));
	assert_int_equal(fscan_gpio_fake_button(gpio, false), 0);
	assert_true(rig.wait_state(State::capturing, 2000) || rig.mcu.fired() == 1);
	assert_true(rig.wait_state(State::idle));
	assert_int_equal(rig.mcu.fired(), 1);
	assert_int_equal(fscan_gpio_fake_output(gpio, FSCAN_GPIO_LED), 0);
	assert_string_equal(rig.ask({{"cmd", "last"}})["last"]["state"].get<std::string>().c_str(), "delivered");
}

static void test_mcu_unplugged_mid_scan(void **)
{
	Rig rig;
	rig.mcu.unplug_on_fire();
	json done = rig.scan("UNPLUG-1");
	assert_false(done["ok"].get<bool>());
	assert_string_equal(done["scan"]["state"].get<std::string>().c_str(), "failed");
	assert_string_equal(done["scan"]["failed_stage"].get<std::string>().c_str(), "capturing");
	// the firmware acknowledged the fire and started the sequence; the link went before its report
	const std::string err = done["scan"]["error"];
	std::printf("  %s\n", err.c_str());
	assert_non_null(std::strstr(err.c_str(), "MCU waiting for the report: link lost"));
	json st = rig.ask({{"cmd", "status"}});
	assert_string_equal(st["state"].get<std::string>().c_str(), "error");
	assert_string_equal(st["mcu"].get<std::string>().c_str(), "disconnected");
	json refused = rig.ask({{"cmd", "scan"}, {"patient", "UNPLUG-2"}});
	assert_string_equal(refused["error"].get<std::string>().c_str(), "unavailable");
	// nothing reached the share
	struct stat s;
	assert_int_equal(stat((rig.cfg.share_dir + "/UNPLUG-1").c_str(), &s), -1);
	rig.mcu.replug();
	assert_true(rig.wait_state(State::idle, 3000));
	assert_true(rig.scan("UNPLUG-3")["ok"].get<bool>());
}

static void test_mcu_unplugged_while_idle(void **)
{
	Rig rig;
	rig.mcu.unplug();
	assert_true(rig.wait_state(State::error, 2000));
	assert_non_null(std::strstr(rig.ask({{"cmd", "status"}})["fault"].get<std::string>().c_str(), "MCU"));
	rig.mcu.replug();
	assert_true(rig.wait_state(State::idle, 3000));
}

static void test_camera_timeout(void **)
{
	Rig rig;
	// the last camera never delivers its pattern frame
	assert_int_equal(fscan_camera_fake_inject(rig.cams->handle(), 3, 0, FSCAN_CAMERA_FAKE_TIMEOUT), 0);
	json done = rig.scan("CAMTIMEOUT");
	assert_false(done["ok"].get<bool>());
	assert_non_null(std::strstr(done["scan"]["error"].get<std::string>().c_str(), "no frame within"));
	assert_true(rig.wait_state(State::idle, 3000));
	assert_true(rig.scan("CAMTIMEOUT-2")["ok"].get<bool>());
}

static void test_frames_from_different_triggers(void **)
{
	Rig rig;
	// camera 1's pattern frame is stamped with the next trigger
	assert_int_equal(fscan_camera_fake_inject(rig.cams->handle(), 1, 0, FSCAN_CAMERA_FAKE_WRONG_TRIGGER), 0);
	json done = rig.scan("MIXED");
	assert_false(done["ok"].get<bool>());
	const std::string err = done["scan"]["error"];
	assert_non_null(std::strstr(err.c_str(), "frames from different triggers"));
	assert_non_null(std::strstr(err.c_str(), "camera 1: frame of another trigger"));
	struct stat s;
	assert_int_equal(stat((rig.cfg.share_dir + "/MIXED").c_str(), &s), -1);
	assert_true(rig.wait_state(State::idle, 3000));
	assert_true(rig.scan("MIXED-2")["ok"].get<bool>());
}

static void test_reconstruction_failure(void **)
{
	Rig rig;
	rig.recon->fail_next_run();
	json done = rig.scan("RECONFAIL");
	assert_false(done["ok"].get<bool>());
	assert_string_equal(done["scan"]["failed_stage"].get<std::string>().c_str(), "reconstructing");
	assert_true(rig.wait_state(State::idle, 2000));
	assert_no_log_mentions("RECONFAIL");
}

static void test_check_capture_skew(void **)
{
	DriverCameras cams("fake", "", 4, 8000, 1000);
	assert_true(cams.open().ok());
	assert_true(cams.prepare().ok());
	TriggerReport r;
	r.sequence = 5;
	Capture c;
	assert_true(cams.collect(r, 100, &c).ok());
	assert_true(check_capture(c, 4, 1000).ok());
	// A frame of another trigger, named with both numbers (the driver's fake is caught by the
	// driver first: test_frames_from_different_triggers).
	c.frames[1].trigger = 6;
	facescan::Status mixed = check_capture(c, 4, 1000);
	assert_int_equal(mixed.code(), -EPROTO);
	assert_non_null(std::strstr(mixed.message().c_str(), "camera 1: frame of trigger 6, expected 5"));
	c.frames[1].trigger = 5;
	c.frames[2].timestamp_ns = c.frames[0].timestamp_ns + 2000000; // 2 ms after camera 0's
	facescan::Status s = check_capture(c, 4, 1000);
	assert_int_equal(s.code(), -EPROTO);
	assert_non_null(std::strstr(s.message().c_str(), "2000 us apart"));
	c.frames.erase(c.frames.begin() + 3);
	assert_non_null(std::strstr(check_capture(c, 4, 1000).message().c_str(), "camera 3: no pattern frame"));
}

// A second daemon on the same spool or socket is refused before it touches anything: it ran
// crash recovery on the live spool and declared the running scan failed.
static void test_second_instance_refused(void **)
{
	Rig rig(Mode::clinic, 1500);
	json first = rig.ask({{"cmd", "scan"}, {"patient", "LIVE-1"}});
	assert_true(first["ok"].get<bool>());
	assert_true(rig.wait_state(State::writing, 3000));
	const std::string current = rig.cfg.spool_dir + "/state/current.json";
	const std::string before = slurp(current);
	assert_false(before.empty());
	facescan::Status s = start_another(rig.cfg);
	std::printf("  same config: %s\n", s.message().c_str());
	assert_int_equal(s.code(), -EBUSY);
	assert_non_null(std::strstr(s.message().c_str(), "another facescand"));
	Config other_socket = rig.cfg;
	other_socket.socket_path = rig.dir + "/sock2";
	assert_int_equal(start_another(other_socket).code(), -EBUSY);
	struct stat st;
	assert_int_not_equal(stat(other_socket.socket_path.c_str(), &st), 0);
	Config other_spool = rig.cfg;
	other_spool.spool_dir = rig.dir + "/spool2";
	assert_int_equal(start_another(other_spool).code(), -EBUSY);
	// the live socket and the running scan are untouched, and it is delivered
	assert_int_equal(stat(rig.cfg.socket_path.c_str(), &st), 0);
	assert_true(S_ISSOCK(st.st_mode));
	assert_true(rig.wait_state(State::idle));
	json last = rig.ask({{"cmd", "last"}})["last"];
	assert_string_equal(last["scan_id"].get<std::string>().c_str(), first["scan_id"].get<std::string>().c_str());
	assert_string_equal(last["state"].get<std::string>().c_str(), "delivered");
}

// A config in a fresh scratch directory (returned in *ret_dir; the test removes it): share and
// spool inside it, the socket at `socket_name`, the fake MCU.
static Config scratch_config(const std::string &socket_name, std::string *ret_dir)
{
	char t[] = "/tmp/facescand-test-XXXXXX";
	assert_non_null(mkdtemp(t));
	*ret_dir = t;
	Config cfg;
	cfg.share_dir = *ret_dir + "/share";
	cfg.spool_dir = *ret_dir + "/spool";
	cfg.socket_path = *ret_dir + "/" + socket_name;
	cfg.serial_device = "fake";
	return cfg;
}

// socket_path naming a regular file: refused, the file kept (it was deleted and replaced).
static void test_socket_path_not_a_socket(void **)
{
	std::string dir;
	Config cfg = scratch_config("important.txt", &dir);
	{
		std::ofstream(cfg.socket_path) << "keep me\n";
	}
	facescan::Status s = start_another(cfg);
	std::printf("  %s\n", s.message().c_str());
	assert_int_equal(s.code(), -EEXIST);
	assert_non_null(std::strstr(s.message().c_str(), "not a socket"));
	assert_string_equal(slurp(cfg.socket_path).c_str(), "keep me\n");
	std::string cmd = "rm -rf '" + dir + "'";
	assert_int_equal(std::system(cmd.c_str()), 0);
}

// socket_group: the daemon's own group needs no chown (the unit's SystemCallFilter denies it);
// the socket has that group. A group that does not exist refuses the start and says so.
static void test_socket_group(void **)
{
	std::string dir;
	Config cfg = scratch_config("sock", &dir);
	const struct group *own = getgrgid(getegid());
	assert_non_null(own);
	cfg.socket_group = own->gr_name;
	{
		Config booth = cfg;
		booth.camera_backend = "fake";
		booth.recon_backend = "fake";
		Daemon d(cfg, fake_booth(booth));
		facescan::Status s = d.start();
		assert_true(s.ok());
		struct stat st;
		assert_int_equal(stat(cfg.socket_path.c_str(), &st), 0);
		assert_int_equal(st.st_gid, getegid());
	}
	cfg.socket_group = "no-such-group-facescan";
	facescan::Status s = start_another(cfg);
	std::printf("  %s\n", s.message().c_str());
	assert_false(s.ok());
	assert_non_null(std::strstr(s.message().c_str(), "no such group"));
	std::string cmd = "rm -rf '" + dir + "'";
	assert_int_equal(std::system(cmd.c_str()), 0);
}

// 32 idle connections locked every client out for ~29 s; a byte every 20 s held a slot forever.
static void test_idle_and_slow_clients(void **)
{
	Rig rig(Mode::clinic, 0, nullptr, 500);
	std::vector<int> idle;
	for (int i = 0; i < 40; i++)
		idle.push_back(connect_to(rig.cfg.socket_path));
	auto t0 = std::chrono::steady_clock::now();
	json st = rig.ask({{"cmd", "status"}});
	double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
	std::printf("  status with 40 idle connections open: %.0f ms\n", ms);
	assert_true(st["ok"].get<bool>());
	assert_true(ms < 400); // before the idle ones time out: they made room, nobody waited
	// A client trickling a byte every 100 ms is closed at its deadline, not kept alive.
	int slow = connect_to(rig.cfg.socket_path);
	const std::string req = "{\"cmd\": \"status\", \"pad\": \"" + std::string(40, 'x') + "\"}\n";
	t0 = std::chrono::steady_clock::now();
	bool closed = false;
	for (size_t i = 0; i < req.size() && !closed; i++) {
		if (::send(slow, &req[i], 1, MSG_NOSIGNAL) != 1)
			closed = true;
		std::this_thread::sleep_for(std::chrono::milliseconds(100));
		char c;
		ssize_t n = recv(slow, &c, 1, MSG_DONTWAIT);
		if (n == 0 || (n < 0 && errno != EAGAIN))
			closed = true;
	}
	ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
	std::printf("  trickling client closed after %.0f ms\n", ms);
	assert_true(closed);
	assert_true(ms < 1500);
	close(slow);
	for (int fd : idle)
		close(fd);
	bool logged = false;
	{
		std::lock_guard<std::mutex> lock(log_mu);
		for (const std::string &l : log_lines)
			logged = logged || l.find("control: closed") != std::string::npos;
	}
	assert_true(logged);
	assert_true(rig.scan("AFTER-SLOW")["ok"].get<bool>());
}

// A spool that cannot take the scan is found before anything is captured, not after.
static void test_unwritable_spool_refuses_before_capture(void **)
{
	Rig rig;
	const std::string queue = rig.cfg.spool_dir + "/queue";
	assert_int_equal(rmdir(queue.c_str()), 0);
	std::ofstream(queue) << "not a directory"; // as root, a file is what no write gets past
	json r = rig.ask({{"cmd", "scan"}, {"patient", "RO-1"}});
	std::printf("  %s\n", r.dump().c_str());
	assert_false(r["ok"].get<bool>());
	assert_string_equal(r["error"].get<std::string>().c_str(), "unavailable");
	assert_non_null(std::strstr(r["message"].get<std::string>().c_str(), "not writable"));
	assert_int_equal(rig.mcu.fired(), 0);
	assert_int_equal(static_cast<int>(rig.d->state()), static_cast<int>(State::idle));
	unlink(queue.c_str());
	mkdir(queue.c_str(), 0750);
	assert_true(rig.scan("RO-2")["ok"].get<bool>());
}

// In clinic mode the button starts nothing: the request says so instead of answering ok.
static void test_button_in_clinic_mode(void **)
{
	Rig rig;
	json r = rig.ask({{"cmd", "button"}});
	assert_false(r["ok"].get<bool>());
	assert_string_equal(r["error"].get<std::string>().c_str(), "unsupported");
	assert_non_null(std::strstr(r["message"].get<std::string>().c_str(), "booth mode"));
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_scan_over_socket),
		cmocka_unit_test(test_socket_mode_and_busy),
		cmocka_unit_test(test_malformed_and_oversize),
		cmocka_unit_test(test_booth_button),
		cmocka_unit_test(test_gpio_mcu_watched_not_polled),
		cmocka_unit_test(test_gpio_button_and_led),
		cmocka_unit_test(test_mcu_unplugged_mid_scan),
		cmocka_unit_test(test_mcu_unplugged_while_idle),
		cmocka_unit_test(test_camera_timeout),
		cmocka_unit_test(test_frames_from_different_triggers),
		cmocka_unit_test(test_reconstruction_failure),
		cmocka_unit_test(test_check_capture_skew),
		cmocka_unit_test(test_second_instance_refused),
		cmocka_unit_test(test_socket_path_not_a_socket),
		cmocka_unit_test(test_socket_group),
		cmocka_unit_test(test_idle_and_slow_clients),
		cmocka_unit_test(test_unwritable_spool_refuses_before_capture),
		cmocka_unit_test(test_button_in_clinic_mode),
	};
	return cmocka_run_group_tests(tests, setup, teardown);
}
