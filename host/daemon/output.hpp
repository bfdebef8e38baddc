// Names of a scan's output: <share>/<patient-id>/<UTC time>_<scan-id>.{drc,png,json}.
#pragma once

#include <chrono>
#include <string>

namespace facescan::daemon {

/// 12 lowercase hex digits from the system's random source.
std::string new_scan_id();
/// "20261124T214510Z" (UTC, no separators that SMB shares dislike).
std::string utc_compact(std::chrono::system_clock::time_point t);
/// "2026-11-24T21:45:10.123Z"
std::string utc_iso(std::chrono::system_clock::time_point t);
/// "<utc_compact>_<scan-id>": the common stem of a scan's files.
std::string output_base(std::chrono::system_clock::time_point t, const std::string &scan_id);

} // namespace facescan::daemon
