#include "daemon/config.hpp"

#include "capture/capture_set.hpp"
#include "daemon/patient_id.hpp"
#include "dicom/dicom.hpp"

#include <cerrno>
#include <climits>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>

namespace facescan::daemon {

namespace {

using Setter = std::function<std::string(Config &, const std::string &)>; // "" = ok, else reason
using Getter = std::function<std::string(const Config &)>;

struct Key {
	const char *name;
	const char *doc;
	Setter set;
	Getter get;
};

Setter int_in(int Config::*field, long lo, long hi)
{
	return [field, lo, hi](Config &c, const std::string &v) -> std::string {
		if (v.empty())
			return "empty value";
		char *end = nullptr;
		errno = 0;
		long n = std::strtol(v.c_str(), &end, 10);
		if (errno || *end)
			return "'" + v + "' is not an integer";
		if (n < lo || n > hi)
			return v + " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
		c.*field = static_cast<int>(n);
		return "";
	};
}

Getter int_of(int Config::*field)
{
	return [field](const Config &c) { return std::to_string(c.*field); };
}

Setter path_in(std::string Config::*field, bool may_be_empty)
{
	return [field, may_be_empty](Config &c, const std::string &v) -> std::string {
		if (v.empty())
			return may_be_empty ? (c.*field = v, "") : "empty value";
		if (v[0] != '/')
			return "'" + v + "' is not an absolute path";
		c.*field = v;
		return "";
	};
}

Setter word_in(std::string Config::*field, std::set<std::string> allowed)
{
	return [field, allowed](Config &c, const std::string &v) -> std::string {
		if (!allowed.empty() && !allowed.count(v)) {
			std::string list;
			for (const auto &a : allowed)
				list += (list.empty() ? "" : ", ") + a;
			return "'" + v + "' is not one of: " + list;
		}
		if (allowed.empty() && v.empty())
			return "empty value";
		c.*field = v;
		return "";
	};
}

// A word of printable ASCII (no spaces): AE titles, host names, addresses. Checked further
// where the set is complete (the PACS as a whole, in parse_config).
Setter text_in(std::string Config::*field, bool may_be_empty)
{
	return [field, may_be_empty](Config &c, const std::string &v) -> std::string {
		if (v.empty() && !may_be_empty)
			return "empty value";
		if (v.size() > 255)
			return "longer than 255 characters";
		for (char ch : v)
			if (static_cast<unsigned char>(ch) <= 0x20 || static_cast<unsigned char>(ch) >= 0x7f)
				return "'" + v + "' holds a space or a character outside printable ASCII";
		c.*field = v;
		return "";
	};
}

Getter bool_of(bool Config::*field)
{
	return [field](const Config &c) { return std::string(c.*field ? "true" : "false"); };
}

Getter str_of(std::string Config::*field)
{
	return [field](const Config &c) { return c.*field; };
}

Setter bool_in(bool Config::*field)
{
	return [field](Config &c, const std::string &v) -> std::string {
		if (v == "true" || v == "yes" || v == "1")
			c.*field = true;
		else if (v == "false" || v == "no" || v == "0")
			c.*field = false;
		else
			return "'" + v + "' is not a boolean (true/false)";
		return "";
	};
}

const std::vector<Key> &keys()
{
	static const std::vector<Key> table = {
		{"mode", "clinic: scans are requested over the socket; booth: the button starts them",
		 [](Config &c, const std::string &v) -> std::string {
			 if (v == "clinic")
				 c.mode = Mode::clinic;
			 else if (v == "booth")
				 c.mode = Mode::booth;
			 else
				 return "'" + v + "' is not one of: booth, clinic";
			 return "";
		 },
		 [](const Config &c) { return std::string(mode_name(c.mode)); }},
		{"share_dir", "the clinic share; meshes land in <share_dir>/<patient-id>/ (never created)",
		 path_in(&Config::share_dir, false), str_of(&Config::share_dir)},
		{"spool_dir", "local queue for scans the share cannot take yet, and the daemon's state",
		 path_in(&Config::spool_dir, false), str_of(&Config::spool_dir)},
		{"share_marker", "a file that must exist at the share's root, or the share counts as unmounted (scans are spooled); empty: none",
		 [](Config &c, const std::string &v) -> std::string {
			 if (v.find('/') != std::string::npos || v == "." || v == "..")
				 return "'" + v + "' is not a file name";
			 c.share_marker = v;
			 return "";
		 },
		 str_of(&Config::share_marker)},
		{"socket_path", "unix control socket (mode 0660)", path_in(&Config::socket_path, false),
		 str_of(&Config::socket_path)},
		{"socket_group", "group that may use the socket; empty: the daemon's own group",
		 [](Config &c, const std::string &v) -> std::string {
			 for (char ch : v)
				 if (!(isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-'))
					 return "'" + v + "' is not a group name";
			 c.socket_group = v;
			 return "";
		 },
		 str_of(&Config::socket_group)},
		{"camera_backend", "simulated | replay | libcamera | fake",
		 word_in(&Config::camera_backend, {"simulated", "replay", "libcamera", "fake"}),
		 str_of(&Config::camera_backend)},
		{"camera_count", "cameras in the booth", int_in(&Config::camera_count, 1, 16),
		 int_of(&Config::camera_count)},
		{"replay_dir", "capture set played back by the replay backend",
		 path_in(&Config::replay_dir, true), str_of(&Config::replay_dir)},
		{"sim_scene", "scene rendered by the simulated backend", word_in(&Config::sim_scene, {}),
		 str_of(&Config::sim_scene)},
		{"sim_scale_percent", "simulated camera resolution in % of the rig's (1600x1200 at 100)",
		 int_in(&Config::sim_scale_percent, 10, 400), int_of(&Config::sim_scale_percent)},
		{"sim_camera_faults",
		 "fault tests only: a file read at each simulated scan, 'drop CAMERA' or 'delay CAMERA MS'; empty: none",
		 path_in(&Config::sim_camera_faults, true), str_of(&Config::sim_camera_faults)},
		{"serial_device", "tty of the trigger MCU, or 'fake' for the in-process MCU",
		 [](Config &c, const std::string &v) -> std::string {
			 if (v != "fake" && (v.empty() || v[0] != '/'))
				 return "'" + v + "' is neither 'fake' nor an absolute device path";
			 c.serial_device = v;
			 return "";
		 },
		 str_of(&Config::serial_device)},
		{"serial_baud", "baud rate of the MCU link", int_in(&Config::serial_baud, 1200, 4000000),
		 int_of(&Config::serial_baud)},
		{"button_source", "none | mcu (the firmware's button event) | gpio (a libgpiod line)",
		 [](Config &c, const std::string &v) -> std::string {
			 if (v == "none")
				 c.button_source = ButtonSource::none;
			 else if (v == "mcu")
				 c.button_source = ButtonSource::mcu;
			 else if (v == "gpio")
				 c.button_source = ButtonSource::gpio;
			 else
				 return "'" + v + "' is not one of: gpio, mcu, none";
			 return "";
		 },
		 [](const Config &c) {
			 return std::string(c.button_source == ButtonSource::none  ? "none"
					    : c.button_source == ButtonSource::mcu ? "mcu"
										   : "gpio");
		 }},
		{"gpio_chip", "gpiochip of the button, LED and MCU reset lines",
		 word_in(&Config::gpio_chip, {}), str_of(&Config::gpio_chip)},
		{"gpio_button_line", "line offset of the booth button; -1: not wired",
		 int_in(&Config::gpio_button_line, -1, 1023), int_of(&Config::gpio_button_line)},
		{"gpio_led_line", "line offset of the status LED; -1: not wired",
		 int_in(&Config::gpio_led_line, -1, 1023), int_of(&Config::gpio_led_line)},
		{"gpio_mcu_reset_line", "line offset of the MCU reset; -1: not wired",
		 int_in(&Config::gpio_mcu_reset_line, -1, 1023), int_of(&Config::gpio_mcu_reset_line)},
		{"booth_patient_id", "patient id of a button press when no scan is armed",
		 word_in(&Config::booth_patient_id, {}), str_of(&Config::booth_patient_id)},
		{"arm_timeout_ms", "booth mode: how long an armed scan waits for the button",
		 int_in(&Config::arm_timeout_ms, 1000, 3600000), int_of(&Config::arm_timeout_ms)},
		{"mcu_timeout_ms", "reply and trigger-report timeout of the MCU",
		 int_in(&Config::mcu_timeout_ms, 50, 60000), int_of(&Config::mcu_timeout_ms)},
		{"capture_timeout_ms", "time for all frames of one trigger to arrive",
		 int_in(&Config::capture_timeout_ms, 50, 600000), int_of(&Config::capture_timeout_ms)},
		{"max_frame_skew_us", "sensor timestamps of one trigger may differ this much",
		 int_in(&Config::max_frame_skew_us, 0, 1000000), int_of(&Config::max_frame_skew_us)},
		{"projector_settle_us", "firmware: projectors on → first shutter",
		 int_in(&Config::projector_settle_us, 0, 1000000), int_of(&Config::projector_settle_us)},
		{"exposure_us", "firmware: shutter pulse width of the pattern frames",
		 int_in(&Config::exposure_us, 10, 1000000), int_of(&Config::exposure_us)},
		{"texture_exposure_us", "firmware: shutter pulse width of the texture frames",
		 int_in(&Config::texture_exposure_us, 10, 1000000), int_of(&Config::texture_exposure_us)},
		{"recon_backend", "pipeline (host/recon) | fake (a fixed test mesh)",
		 word_in(&Config::recon_backend, {"pipeline", "fake"}), str_of(&Config::recon_backend)},
		{"calibration_file", "calibration.yaml of the booth (facescan calibrate), for libcamera frames",
		 path_in(&Config::calibration_file, false), str_of(&Config::calibration_file)},
		{"pattern_id", "id of the slide the projectors throw; empty: this build's default pattern",
		 [](Config &c, const std::string &v) -> std::string {
			 for (char ch : v)
				 if (!(isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_' || ch == '.'))
					 return "'" + v + "' is not a pattern id";
			 c.pattern_id = v;
			 return "";
		 },
		 str_of(&Config::pattern_id)},
		{"min_free_mb", "free space the share must have, else the scan is spooled",
		 int_in(&Config::min_free_mb, 0, 1000000), int_of(&Config::min_free_mb)},
		{"spool_retry_ms", "how often spooled scans are offered to the share",
		 int_in(&Config::spool_retry_ms, 100, 3600000), int_of(&Config::spool_retry_ms)},
		{"stage_timeout_ms", "a stage running longer than this stops the watchdog pings",
		 int_in(&Config::stage_timeout_ms, 1000, 3600000), int_of(&Config::stage_timeout_ms)},
		{"keep_captures", "keep each raw capture set in <spool_dir>/captures/",
		 bool_in(&Config::keep_captures),
		 [](const Config &c) { return std::string(c.keep_captures ? "true" : "false"); }},
		{"client_timeout_ms", "a control client must send a whole request within this (then it is closed)",
		 int_in(&Config::client_timeout_ms, 100, 600000), int_of(&Config::client_timeout_ms)},
		{"recon_timeout_ms", "pipeline: the reconstruction worker process is killed after this",
		 int_in(&Config::recon_timeout_ms, 100, 3600000), int_of(&Config::recon_timeout_ms)},
		{"recon_memory_mb", "pipeline: address-space limit of the worker process in MiB; 0: none",
		 int_in(&Config::recon_memory_mb, 0, 1048576), int_of(&Config::recon_memory_mb)},
		{"recon_worker", "pipeline: the facescan CLI whose recon verb is the worker; empty: the facescan beside facescand",
		 path_in(&Config::recon_worker, true), str_of(&Config::recon_worker)},
		{"output_glb", "write <base>.glb (glTF binary, Draco, texture embedded) with each scan",
		 bool_in(&Config::output_glb), bool_of(&Config::output_glb)},
		{"output_thumbnail", "write <base>_thumb.png (front and +-45 degree renders)",
		 bool_in(&Config::output_thumbnail), bool_of(&Config::output_thumbnail)},
		{"output_stl", "write <base>.stl (binary STL, mm)", bool_in(&Config::output_stl),
		 bool_of(&Config::output_stl)},
		{"output_obj", "write <base>.obj + <base>.mtl (texture <base>.png, mm)", bool_in(&Config::output_obj),
		 bool_of(&Config::output_obj)},
		{"output_dicom", "write <base>.dcm (DICOM Encapsulated STL) to the share",
		 bool_in(&Config::output_dicom), bool_of(&Config::output_dicom)},
		{"pacs_called_ae", "AE title of the PACS that receives every scan by C-STORE; empty: none",
		 text_in(&Config::pacs_called_ae, true), str_of(&Config::pacs_called_ae)},
		{"pacs_host", "host name or address of the PACS", text_in(&Config::pacs_host, true),
		 str_of(&Config::pacs_host)},
		{"pacs_port", "DICOM port of the PACS", int_in(&Config::pacs_port, 1, 65535), int_of(&Config::pacs_port)},
		{"pacs_calling_ae", "our AE title towards the PACS", text_in(&Config::pacs_calling_ae, false),
		 str_of(&Config::pacs_calling_ae)},
		{"pacs_timeout_s", "connect / association / message timeout towards the PACS",
		 int_in(&Config::pacs_timeout_s, 1, 600), int_of(&Config::pacs_timeout_s)},
		{"viewer_port", "serve the web viewer of the share on this port; 0: off",
		 int_in(&Config::viewer_port, 0, 65535), int_of(&Config::viewer_port)},
		{"viewer_bind", "address the viewer listens on (127.0.0.1: this machine only)",
		 text_in(&Config::viewer_bind, false), str_of(&Config::viewer_bind)},
	};
	return table;
}

std::string trim(const std::string &s)
{
	size_t b = s.find_first_not_of(" \t\r");
	if (b == std::string::npos)
		return "";
	size_t e = s.find_last_not_of(" \t\r");
	return s.substr(b, e - b + 1);
}

} // namespace

const char *mode_name(Mode m)
{
	return m == Mode::booth ? "booth" : "clinic";
}

Status parse_config(const std::string &text, const std::string &name, Config *ret_config)
{
	Config c = *ret_config;
	std::set<std::string> seen;
	std::istringstream in(text);
	std::string raw;
	int lineno = 0;
	while (std::getline(in, raw)) {
		lineno++;
		auto fail = [&](const std::string &why) {
			return Status::error(EINVAL, name + ":" + std::to_string(lineno) + ": " + why);
		};
		for (char ch : raw)
			if ((static_cast<unsigned char>(ch) < 0x20 && ch != '\t' && ch != '\r') || ch == 0x7f)
				return fail("control character in line");
		std::string line = trim(raw);
		if (line.empty() || line[0] == '#')
			continue;
		size_t eq = line.find('=');
		if (eq == std::string::npos)
			return fail("expected 'key = value', got '" + line + "'");
		std::string key = trim(line.substr(0, eq));
		std::string value = trim(line.substr(eq + 1));
		if (key.empty())
			return fail("missing key before '='");
		const Key *k = nullptr;
		for (const Key &candidate : keys())
			if (key == candidate.name)
				k = &candidate;
		if (!k)
			return fail("unknown key '" + key + "'");
		if (!seen.insert(key).second)
			return fail("key '" + key + "' given twice");
		std::string why = k->set(c, value);
		if (!why.empty())
			return fail(key + ": " + why);
	}
	if (!c.sim_camera_faults.empty() && c.camera_backend != "simulated")
		return Status::error(EINVAL, name + ": sim_camera_faults needs camera_backend = simulated");
	if (c.camera_backend == "replay" && c.replay_dir.empty())
		return Status::error(EINVAL, name + ": camera_backend = replay needs replay_dir");
	if (c.button_source == ButtonSource::gpio &&
	    (c.gpio_button_line < 0 || c.gpio_led_line < 0 || c.gpio_mcu_reset_line < 0))
		return Status::error(EINVAL, name + ": button_source = gpio needs gpio_button_line, gpio_led_line "
					     "and gpio_mcu_reset_line");
	Status id = validate_patient_id(c.booth_patient_id);
	if (!id.ok())
		return Status::error(EINVAL, name + ": booth_patient_id: " + id.message());
	if (c.recon_timeout_ms >= c.stage_timeout_ms)
		return Status::error(EINVAL, name + ": recon_timeout_ms must be below stage_timeout_ms, or the watchdog "
					     "restarts the daemon before the worker is killed");
	if (!c.pacs_called_ae.empty()) {
		dicom::Pacs pacs{c.pacs_calling_ae, c.pacs_called_ae, c.pacs_host, c.pacs_port, c.pacs_timeout_s};
		Status p = dicom::validate_pacs(pacs);
		if (!p.ok())
			return Status::error(EINVAL, name + ": pacs: " + p.message());
	}
	if (c.share_dir == c.spool_dir)
		return Status::error(EINVAL, name + ": share_dir and spool_dir must differ");
	*ret_config = c;
	return Status();
}

Status load_config(const std::string &path, Config *ret_config)
{
	// A directory opened as a stream reads as empty: `--check` said ok to one.
	std::string text;
	Status s = read_regular_file(path, 1 << 20, &text);
	if (!s.ok())
		return Status::error(s.code(), s.message() + " (the config file)");
	return parse_config(text, path, ret_config);
}

std::string default_config_text()
{
	Config defaults;
	std::string out = "# facescand configuration (/etc/facescan/facescand.conf). Defaults shown.\n";
	for (const Key &k : keys()) {
		out += "\n# ";
		out += k.doc;
		out += "\n";
		out += k.name;
		out += " = " + k.get(defaults) + "\n";
	}
	return out;
}

} // namespace facescan::daemon
