#include "daemon/output.hpp"

#include <cstdio>
#include <ctime>
#include <random>

namespace facescan::daemon {

std::string new_scan_id()
{
	std::random_device rd;
	uint64_t v = (static_cast<uint64_t>(rd()) << 32) ^ rd();
	char buf[17];
	std::snprintf(buf, sizeof buf, "%012llx", static_cast<unsigned long long>(v & 0xffffffffffffULL));
	return buf;
}

static std::tm utc_tm(std::chrono::system_clock::time_point t)
{
	std::time_t tt = std::chrono::system_clock::to_time_t(t);
	std::tm tm{};
	gmtime_r(&tt, &tm);
	return tm;
}

std::string utc_compact(std::chrono::system_clock::time_point t)
{
	std::tm tm = utc_tm(t);
	char buf[32];
	std::strftime(buf, sizeof buf, "%Y%m%dT%H%M%SZ", &tm);
	return buf;
}

std::string utc_iso(std::chrono::system_clock::time_point t)
{
	std::tm tm = utc_tm(t);
	char buf[32];
	std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%S", &tm);
	long ms = static_cast<long>(
		std::chrono::duration_cast<std::chrono::milliseconds>(t.time_since_epoch()).count() % 1000);
	char out[48];
	std::snprintf(out, sizeof out, "%s.%03ldZ", buf, ms);
	return out;
}

std::string output_base(std::chrono::system_clock::time_point t, const std::string &scan_id)
{
	return utc_compact(t) + "_" + scan_id;
}

} // namespace facescan::daemon
