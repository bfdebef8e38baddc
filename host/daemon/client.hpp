// Talking to facescand over its control socket (the CLI verbs and tests use this).
#pragma once

#include "common/status.hpp"

#include <nlohmann/json.hpp>

#include <functional>
#include <string>

namespace facescan::daemon {

/// The socket facescand listens on unless told otherwise: $FACESCAN_SOCKET, else the default.
std::string default_socket_path();

/// Sends one request line and hands every reply line to `on_reply` until it returns false, the
/// daemon closes the connection, or `timeout_ms` passes without a line (-ETIMEDOUT).
/// -ECONNREFUSED / -ENOENT when no daemon listens; -EPROTO for a reply that is not JSON.
Status control_request(const std::string &socket_path, const nlohmann::json &request,
		       const std::function<bool(const nlohmann::json &)> &on_reply, int timeout_ms);

/// Sends raw bytes (tests: malformed and oversize requests) and returns the first reply line
/// ("" if the daemon closed without one).
Status control_raw(const std::string &socket_path, const std::string &bytes, std::string *ret_reply,
		   int timeout_ms);

} // namespace facescan::daemon
