// facescand's log: one line per event on stderr. Under systemd (JOURNAL_STREAM set) each line
// carries a syslog priority prefix "<N>" that journald turns into the entry's priority.
// Rule of the house: no patient data in the log — scans are named by their scan id only.
#pragma once

#include <functional>
#include <string>
#include <syslog.h>

namespace facescan::daemon {

using LogSink = std::function<void(int priority, const std::string &line)>;

/// Replaces where log lines go (tests capture them); nullptr restores stderr.
void set_log_sink(LogSink sink);
void log(int priority, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

} // namespace facescan::daemon
