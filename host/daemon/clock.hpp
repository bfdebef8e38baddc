// The daemon's clock for stage times and deadlines: monotonic, so a wall-clock step (NTP, an
// operator setting the date) neither fires a timer early nor starves one.
#pragma once

#include <chrono>

namespace facescan::daemon {

using Clock = std::chrono::steady_clock;

/// Milliseconds since `t`, fractional: what the logs and the scan records report per stage.
inline double ms_since(Clock::time_point t)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

} // namespace facescan::daemon
