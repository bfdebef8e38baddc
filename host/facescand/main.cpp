// facescand — the booth daemon. Usage: facescand [--config FILE] [--print-config] [--check]
#include "common/version.hpp"
#include "daemon/config.hpp"
#include "daemon/daemon.hpp"
#include "daemon/log.hpp"
#include "daemon/make_backends.hpp"
#include "facescand/sim_booth.hpp"

#include <csignal>
#include <cstdio>
#include <cstring>
#include <getopt.h>
#include <systemd/sd-daemon.h>
#include <unistd.h>

using namespace facescan::daemon;

namespace {

Daemon *running;

void on_signal(int)
{
	if (running)
		running->request_stop();
}

void usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescand [--config FILE] [--check] [--print-config]\n"
		     "  -c, --config FILE   configuration (default /etc/facescan/facescand.conf if it exists)\n"
		     "      --check         validate the configuration and exit\n"
		     "      --print-config  print every key with its default and exit\n"
		     "  -V, --version       print the version\n");
}

} // namespace

int main(int argc, char **argv)
{
	static const option opts[] = {{"config", required_argument, nullptr, 'c'},
				      {"check", no_argument, nullptr, 'k'},
				      {"print-config", no_argument, nullptr, 'p'},
				      {"version", no_argument, nullptr, 'V'},
				      {"help", no_argument, nullptr, 'h'},
				      {nullptr, 0, nullptr, 0}};
	std::string config_path;
	bool explicit_config = false, check_only = false;
	int c;
	while ((c = getopt_long(argc, argv, "c:Vh", opts, nullptr)) != -1) {
		switch (c) {
		case 'c':
			config_path = optarg;
			explicit_config = true;
			break;
		case 'k':
			check_only = true;
			break;
		case 'p':
			std::fputs(default_config_text().c_str(), stdout);
			return 0;
		case 'V':
			std::printf("facescand %s\n", facescan::version());
			return 0;
		case 'h':
			usage(stdout);
			return 0;
		default:
			usage(stderr);
			return 2;
		}
	}
	if (optind < argc) {
		std::fprintf(stderr, "facescand: unexpected argument '%s'\n", argv[optind]);
		usage(stderr);
		return 2;
	}
	Config config;
	if (!explicit_config && access("/etc/facescan/facescand.conf", F_OK) == 0) {
		config_path = "/etc/facescan/facescand.conf";
		explicit_config = true;
	}
	if (explicit_config) {
		facescan::Status s = load_config(config_path, &config);
		if (!s.ok()) {
			log(LOG_ERR, "refusing to start: %s", s.message().c_str());
			return 1;
		}
	}
	if (config.recon_worker.empty()) {
		// The worker is the facescan CLI installed beside us.
		char self[4096];
		ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
		if (n > 0) {
			std::string exe(self, static_cast<size_t>(n));
			config.recon_worker = exe.substr(0, exe.rfind('/') + 1) + "facescan";
		}
	}
	if (check_only) {
		std::printf("%s: ok\n", explicit_config ? config_path.c_str() : "(defaults)");
		return 0;
	}
	Backends backends;
	const std::string faults = config.sim_camera_faults;
	facescan::Status s = make_backends(
		config,
		[faults](const std::string &scene, double scale, std::unique_ptr<facescan::daemon::SimulatedBooth> *ret) {
			return facescan::facescand::make_sim_booth(scene, scale, faults, ret);
		},
		&backends);
	if (!s.ok()) {
		log(LOG_ERR, "refusing to start: %s", s.message().c_str());
		return 1;
	}
	Daemon daemon(config, std::move(backends));
	daemon.set_notify([](const std::string &msg) { sd_notify(0, msg.c_str()); });
	uint64_t wd = 0;
	if (sd_watchdog_enabled(0, &wd) > 0)
		daemon.set_watchdog_usec(wd);
	s = daemon.start();
	if (!s.ok()) {
		log(LOG_ERR, "cannot start: %s", s.message().c_str());
		return 1;
	}
	running = &daemon;
	struct sigaction sa = {};
	sa.sa_handler = on_signal;
	sigaction(SIGTERM, &sa, nullptr);
	sigaction(SIGINT, &sa, nullptr);
	signal(SIGPIPE, SIG_IGN);
	s = daemon.run();
	running = nullptr;
	if (!s.ok()) {
		log(LOG_ERR, "%s", s.message().c_str());
		return 1;
	}
	return 0;
}
