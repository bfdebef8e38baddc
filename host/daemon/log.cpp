#include "daemon/log.hpp"

#include <cstdarg>
#include <cstdio>
#include <cstdlib>
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
	else
		std::fprintf(stderr, "facescand: %s\n", buf);
	std::fflush(stderr);
}

} // namespace facescan::daemon
