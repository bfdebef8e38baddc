// facescan status: what facescand is doing now.
#include "daemon/report_text.hpp"
#include "facescan/daemon_query.hpp"

namespace facescan::cli {

int status_main(int argc, char **argv)
{
	static const DaemonQuery query = {
		"status", "Prints facescand's state, the scan in flight, the MCU link and the spool.",
		[](const nlohmann::json &reply) { return daemon::status_text(reply); }};
	return run_daemon_query(query, argc, argv);
}

} // namespace facescan::cli
