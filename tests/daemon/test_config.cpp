// facescand's config: defaults, every kind of bad line refused with its line number.
#include "daemon/config.hpp"


#include <cstring>

#include <cstdio>
#include <string>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

using namespace facescan::daemon;

static void expect_refused(const std::string &text, const char *fragment)
{
	Config c;
	facescan::Status s = parse_config(text, "t.conf", &c);
	if (s.ok() || s.message().find(fragment) == std::string::npos)
		fail_msg("config '%s': want error containing '%s', got '%s'", text.c_str(), fragment,
			 s.message().c_str());
	assert_int_equal(s.code(), -EINVAL);
}

static void test_defaults(void **)
{
	Config c;
	assert_true(parse_config("", "t.conf", &c).ok());
	assert_int_equal(static_cast<int>(c.mode), static_cast<int>(Mode::clinic));
	assert_string_equal(c.share_dir.c_str(), "/srv/facescan/share");
	assert_string_equal(c.spool_dir.c_str(), "/var/spool/facescan");
	assert_string_equal(c.socket_path.c_str(), "/run/facescan/facescand.sock");
	assert_int_equal(c.camera_count, 4);
	assert_int_equal(c.capture_timeout_ms, 5000);
	// The printed defaults parse back to the same defaults.
	Config d;
	facescan::Status s = parse_config(default_config_text(), "defaults", &d);
	assert_true(s.ok());
	assert_string_equal(d.share_dir.c_str(), c.share_dir.c_str());
	assert_int_equal(d.mcu_timeout_ms, c.mcu_timeout_ms);
}

static void test_values(void **)
{
	Config c;
	facescan::Status s = parse_config("# comment\n\n  mode = booth  \nshare_dir=/mnt/share\n"
					  "camera_backend = replay\nreplay_dir = /data/set1\n"
					  "keep_captures = yes\ncapture_timeout_ms = 250\r\n",
					  "t.conf", &c);
	assert_true(s.ok());
	assert_int_equal(static_cast<int>(c.mode), static_cast<int>(Mode::booth));
	assert_string_equal(c.share_dir.c_str(), "/mnt/share");
	assert_string_equal(c.camera_backend.c_str(), "replay");
	assert_true(c.keep_captures);
	assert_int_equal(c.capture_timeout_ms, 250);
}

static void test_refused_lines(void **)
{
	expect_refused("mode = clinic\nfrobnicate = 1\n", "t.conf:2: unknown key 'frobnicate'");
	// the fault-test pauses are gone from the shipped daemon (tests slow the share from outside)
	expect_refused("test_delay_write_ms = 1500\n", "t.conf:1: unknown key 'test_delay_write_ms'");
	expect_refused("test_delay_deliver_ms = 1000\n", "t.conf:1: unknown key 'test_delay_deliver_ms'");
	expect_refused("\n\nshare_dir /x\n", "t.conf:3: expected 'key = value'");
	expect_refused("= 3\n", "t.conf:1: missing key");
	expect_refused("mode = kiosk\n", "t.conf:1: mode: 'kiosk' is not one of");
	expect_refused("share_dir = relative/path\n", "t.conf:1: share_dir: 'relative/path' is not an absolute path");
	expect_refused("capture_timeout_ms = 12x\n", "t.conf:1: capture_timeout_ms: '12x' is not an integer");
	expect_refused("capture_timeout_ms = 1\n", "t.conf:1: capture_timeout_ms: 1 is out of range");
	expect_refused("camera_count = 99999999999999999999\n", "is not an integer");
	expect_refused("mode = booth\nmode = clinic\n", "t.conf:2: key 'mode' given twice");
	expect_refused("keep_captures = maybe\n", "t.conf:1: keep_captures: 'maybe' is not a boolean");
	expect_refused("camera_backend = webcam\n", "camera_backend: 'webcam' is not one of");
	expect_refused("serial_device = ttyUSB0\n", "neither 'fake' nor an absolute device path");
	expect_refused("socket_group = a b\n", "is not a group name");
	expect_refused("share_dir = /x\x01y\n", "t.conf:1: control character");
	expect_refused("booth_patient_id = ../etc\n", "booth_patient_id: patient id contains a path separator");
	expect_refused("camera_backend = replay\n", "needs replay_dir");
	// The soak's camera fault knob reaches only the simulated sensor.
	expect_refused("camera_backend = fake\nsim_camera_faults = /tmp/f\n", "sim_camera_faults needs camera_backend = simulated");
	expect_refused("camera_backend = simulated\nsim_camera_faults = f\n", "sim_camera_faults: 'f' is not an absolute path");
	expect_refused("button_source = gpio\n", "needs gpio_button_line");
	expect_refused("share_dir = /a\nspool_dir = /a\n", "must differ");
}

static void test_refused_config_leaves_output_untouched(void **)
{
	Config c;
	c.camera_count = 7;
	assert_false(parse_config("camera_count = 3\nbad line\n", "t.conf", &c).ok());
	assert_int_equal(c.camera_count, 7);
}

static void test_load_missing_file(void **)
{
	Config c;
	facescan::Status s = load_config("/nonexistent/facescand.conf", &c);
	assert_int_equal(s.code(), -ENOENT);
	assert_non_null(std::strstr(s.message().c_str(), "/nonexistent/facescand.conf"));
}

// `facescand --config DIR --check` said ok: a directory read as an empty config.
static void test_load_directory_refused(void **)
{
	Config c;
	facescan::Status s = load_config("/tmp", &c);
	assert_int_equal(s.code(), -EINVAL);
	assert_non_null(std::strstr(s.message().c_str(), "not a regular file"));
	// the worker's deadline must come before the watchdog's
	s = parse_config("recon_timeout_ms = 400000\n", "t.conf", &c);
	assert_int_equal(s.code(), -EINVAL);
	assert_non_null(std::strstr(s.message().c_str(), "stage_timeout_ms"));
	assert_true(parse_config("share_marker = .facescan-share\nclient_timeout_ms = 800\n", "t.conf", &c).ok());
	assert_string_equal(c.share_marker.c_str(), ".facescan-share");
	assert_false(parse_config("share_marker = a/b\n", "t.conf", &c).ok());
}

int main()
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_defaults),
		cmocka_unit_test(test_values),
		cmocka_unit_test(test_refused_lines),
		cmocka_unit_test(test_refused_config_leaves_output_untouched),
		cmocka_unit_test(test_load_missing_file),
		cmocka_unit_test(test_load_directory_refused),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
