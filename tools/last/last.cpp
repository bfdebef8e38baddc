// facescan last: the outcome of the most recent scan.
#include "daemon/report_text.hpp"
#include "facescan/daemon_query.hpp"

namespace facescan::cli {

int last_main(int argc, char **argv)
{
	static const DaemonQuery query = {
		"last", "Prints the most recent scan: outcome, files on the share, times per stage.",
		[](const nlohmann::json &reply) { return daemon::scan_text(reply.value("last", nlohmann::json())); }};
	return run_daemon_query(query, argc, argv);
}

} // namespace facescan::cli
