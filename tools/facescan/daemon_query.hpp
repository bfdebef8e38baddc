// The read-only client verbs (`facescan status`, `facescan last`): one request to facescand's
// control socket, the reply printed as text or, with --json, as the daemon sent it.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace facescan::cli {

struct DaemonQuery {
	const char *verb;	 // the verb's name and the socket command it sends
	const char *description; // one line for --help
	std::string (*render)(const nlohmann::json &reply); // reply → human-readable text
};

/// Parses [--json] [--socket PATH], asks the daemon, prints the reply. Returns the exit code.
int run_daemon_query(const DaemonQuery &query, int argc, char **argv);

} // namespace facescan::cli
