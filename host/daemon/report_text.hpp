// Human-readable text of facescand's replies, shared by `facescan status|last|scan`.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace facescan::daemon {

std::string status_text(const nlohmann::json &status);
/// A scan record (the "last" reply's "last", the "done" event's "scan").
std::string scan_text(const nlohmann::json &scan);

} // namespace facescan::daemon
