#include "daemon/report_text.hpp"

#include <cstdio>

namespace facescan::daemon {

using json = nlohmann::json;

namespace {

std::string str(const json &j, const char *key)
{
	if (!j.contains(key) || j[key].is_null())
		return "";
	return j[key].is_string() ? j[key].get<std::string>() : j[key].dump();
}

std::string ms(const json &v)
{
	char buf[32];
	std::snprintf(buf, sizeof buf, "%.0f ms", v.is_number() ? v.get<double>() : 0.0);
	return buf;
}

} // namespace

std::string status_text(const json &s)
{
	std::string out = "state:        " + str(s, "state");
	if (s.contains("scan_id"))
		out += " (scan " + str(s, "scan_id") + ", " + str(s, "stage_elapsed_ms") + " ms in this stage)";
	out += "\n";
	if (s.contains("fault"))
		out += "fault:        " + str(s, "fault") + "\n";
	out += "mode:         " + str(s, "mode") + "\n";
	out += "MCU:          " + str(s, "mcu");
	if (!str(s, "firmware").empty())
		out += " (" + str(s, "firmware") + ")";
	out += "\n";
	out += "cameras:      " + str(s, "camera_backend") + "\n";
	out += "recon:        " + str(s, "recon_backend") + "\n";
	out += "spooled:      " + str(s, "spool_pending") + " scan(s) waiting for the share\n";
	out += "version:      " + str(s, "version") + "\n";
	return out;
}

std::string scan_text(const json &r)
{
	if (r.is_null())
		return "no scan yet\n";
	std::string out = "scan " + str(r, "scan_id") + ": " + str(r, "state") + "\n";
	if (!str(r, "patient_id").empty())
		out += "  patient:    " + str(r, "patient_id") + "\n";
	if (!str(r, "started_utc").empty())
		out += "  started:    " + str(r, "started_utc") + "\n";
	if (!str(r, "error").empty())
		out += "  error:      " + str(r, "error") + (r.contains("failed_stage") ? " (while " + str(r, "failed_stage") + ")" : "") + "\n";
	if (r.contains("vertices"))
		out += "  vertices:   " + str(r, "vertices") + ", faces: " + str(r, "faces") + "\n";
	if (r.contains("warnings") && r["warnings"].is_array())
		for (const auto &w : r["warnings"])
			if (w.is_string())
				out += "  warning:    " + w.get<std::string>() + "\n";
	if (r.contains("stage_ms") && r["stage_ms"].is_object()) {
		out += "  times:     ";
		for (auto it = r["stage_ms"].begin(); it != r["stage_ms"].end(); ++it)
			out += " " + it.key() + " " + ms(*it);
		out += "\n";
	}
	if (r.contains("files") && r["files"].is_array())
		for (const auto &f : r["files"])
			out += "  file:       " + f.get<std::string>() + "\n";
	if (!str(r, "spool_reason").empty())
		out += "  spooled:    " + str(r, "spool_reason") + "\n";
	return out;
}

} // namespace facescan::daemon
