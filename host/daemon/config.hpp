// facescand's configuration: one `key = value` per line, `#` starts a comment line.
// Every key has a documented default (Config{} holds them; `facescand --print-config` prints
// them as a config file). A bad file is refused as a whole with "FILE:LINE: reason".
#pragma once

#include "common/status.hpp"

#include <string>

namespace facescan::daemon {

enum class Mode { clinic, booth };
enum class ButtonSource { none, mcu, gpio };

struct Config {
	Mode mode = Mode::clinic;                // booth: the button starts scans; clinic: the socket
	std::string share_dir = "/srv/facescan/share";  // the clinic share (mount point); never created
	std::string spool_dir = "/var/spool/facescan";  // local queue + state; created if missing
	std::string share_marker;                // file at the share's root proving it is mounted; "": none
	std::string socket_path = "/run/facescan/facescand.sock";
	std::string socket_group;                // group owning the socket (mode 0660); empty: ours
	std::string camera_backend = "libcamera"; // libcamera | replay | simulated | fake
	int camera_count = 4;
	std::string replay_dir;                  // capture set the replay backend plays back
	std::string sim_scene = "default";       // scene the simulated backend renders
	int sim_scale_percent = 100;             // simulated camera resolution, % of the rig's
	std::string sim_camera_faults;           // fault tests only: a file of camera faults, read per simulated scan
	std::string serial_device = "/dev/ttyACM0"; // tty of the MCU, or "fake" (in-process MCU)
	int serial_baud = 115200;
	ButtonSource button_source = ButtonSource::mcu;
	std::string gpio_chip = "gpiochip0";
	int gpio_button_line = -1;               // -1: not wired
	int gpio_led_line = -1;
	int gpio_mcu_reset_line = -1;
	std::string booth_patient_id = "walk-in"; // patient of a button press with nothing armed
	int arm_timeout_ms = 120000;             // booth mode: an armed scan waits this long for a press
	int mcu_timeout_ms = 2000;               // per MCU command / trigger report
	int capture_timeout_ms = 5000;           // all frames of one trigger
	int max_frame_skew_us = 1000;            // sensor timestamps of one trigger must agree
	int projector_settle_us = 20000;         // firmware timing, sent at every arm
	int exposure_us = 8000;
	int texture_exposure_us = 8000;
	std::string recon_backend = "pipeline";  // pipeline | fake
	std::string calibration_file = "/etc/facescan/calibration.yaml"; // for cameras without a set
	std::string pattern_id;                  // the booth's slide; empty: the default pattern
	int min_free_mb = 64;                    // the share needs this much room or scans are spooled
	int spool_retry_ms = 5000;               // how often spooled scans are offered to the share
	int stage_timeout_ms = 300000;           // a stage running longer stops the watchdog pings
	bool keep_captures = false;              // keep the raw capture set in the spool
	int client_timeout_ms = 5000;            // a control client must send a whole request within this
	int recon_timeout_ms = 240000;           // the reconstruction worker is killed after this
	int recon_memory_mb = 4096;              // address-space limit of the worker (0: none)
	std::string recon_worker;                // the facescan CLI (recon verb = the worker); empty: beside facescand
	// What a scan writes besides .drc/.png/.json (host/daemon/clinic_output.cpp), and where to.
	bool output_glb = true;                  // <base>.glb: glTF binary for browsers and the viewer
	bool output_thumbnail = true;            // <base>_thumb.png: front and ±45° renders
	bool output_stl = false;                 // <base>.stl: binary STL, mm
	bool output_obj = false;                 // <base>.obj + .mtl (texture: <base>.png)
	bool output_dicom = false;               // <base>.dcm on the share (Encapsulated STL)
	std::string pacs_called_ae;              // C-STORE every scan to this PACS; empty: none
	std::string pacs_host;
	int pacs_port = 104;
	std::string pacs_calling_ae = "FACESCAN";
	int pacs_timeout_s = 5;
	int viewer_port = 0;                     // serve the web viewer on this port; 0: off
	std::string viewer_bind = "127.0.0.1";
};

/// Parses the text of a config file on top of the defaults. `name` labels the errors
/// ("NAME:LINE: reason"). Unknown keys, duplicates, bad values and missing '=' are refused.
Status parse_config(const std::string &text, const std::string &name, Config *ret_config);

/// Reads and parses a config file. -ENOENT if it cannot be read.
Status load_config(const std::string &path, Config *ret_config);

/// The defaults as a commented config file (the reference for docs/daemon.md).
std::string default_config_text();

const char *mode_name(Mode m);

} // namespace facescan::daemon
