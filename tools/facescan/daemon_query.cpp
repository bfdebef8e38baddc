#include "daemon_query.hpp"

#include "daemon/client.hpp"

#include <cstdio>
#include <getopt.h>

namespace facescan::cli {

int run_daemon_query(const DaemonQuery &q, int argc, char **argv)
{
	static const option opts[] = {{"socket", required_argument, nullptr, 's'},
				      {"json", no_argument, nullptr, 'j'},
				      {"help", no_argument, nullptr, 'h'},
				      {nullptr, 0, nullptr, 0}};
	std::string sock = daemon::default_socket_path();
	bool as_json = false;
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "s:jh", opts, nullptr)) != -1) {
		switch (c) {
		case 's':
			sock = optarg;
			break;
		case 'j':
			as_json = true;
			break;
		case 'h':
			std::printf("usage: facescan %s [--json] [--socket PATH]\n"
				    "%s\n"
				    "  -j, --json        print the daemon's JSON reply\n"
				    "  -s, --socket PATH control socket (default $FACESCAN_SOCKET or %s)\n",
				    q.verb, q.description, daemon::default_socket_path().c_str());
			return 0;
		default:
			std::fprintf(stderr, "facescan %s: bad arguments (see facescan %s --help)\n",
				     q.verb, q.verb);
			return 2;
		}
	}
	if (optind < argc) {
		std::fprintf(stderr, "facescan %s: unexpected argument '%s'\n", q.verb, argv[optind]);
		return 2;
	}
	nlohmann::json reply;
	Status s = daemon::control_request(
		sock, {{"cmd", q.verb}},
		[&](const nlohmann::json &j) {
			reply = j;
			return false;
		},
		10000);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan %s: %s\n", q.verb, s.message().c_str());
		return 1;
	}
	if (as_json) {
		std::printf("%s\n", reply.dump(1).c_str());
	} else if (!reply.value("ok", false)) {
		std::fprintf(stderr, "facescan %s: %s\n", q.verb, reply.value("message", "refused").c_str());
		return 1;
	} else {
		std::printf("%s", q.render(reply).c_str());
	}
	return reply.value("ok", false) ? 0 : 1;
}

} // namespace facescan::cli
