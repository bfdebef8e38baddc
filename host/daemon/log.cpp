#include "daemon/log.hpp"

#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <mutex>

namespace facescan::daemon {

namespace {
std::mutex log_mu;
LogSink log_sink;
} // namespace

void set_log_sink(LogSink sink)
{
	std::lock_guard<std::mutex> lock(log_mu);
	log_sink = std::move(sink);
}

void log(int priority, const char *fmt, ...)
{
	char buf[1024];
	va_list ap;
	va_start(ap, fmt);
	std::vsnprintf(buf, sizeof buf, fmt, ap);
	va_end(ap);
	std::lock_guard<std::mutex> lock(log_mu);
	if (log_sink) {
		log_sink(priority, buf);
		return;
	}
	if (std::getenv("JOURNAL_STREAM"))
		std::fprintf(stderr, "<%d>%s\n", priority, buf);
	else {
		// Outside journald nothing else stamps the line: UTC, to the millisecond.
		timespec ts{};
		clock_gettime(CLOCK_REALTIME, &ts);
		tm t{};
		gmtime_r(&ts.tv_sec, &t);
		char when[32];
		std::strftime(when, sizeof when, "%Y-%m-%dT%H:%M:%S", &t);
		std::fprintf(stderr, "%s.%03ldZ facescand: %s\n", when, ts.tv_nsec / 1000000, buf);
	}
	std::fflush(stderr);
}

} // namespace facescan::daemon
