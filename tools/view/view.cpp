// facescan view: the web viewer on localhost; facescan thumbnail: a picture of a mesh with the
// project's ray caster (the same framing as the viewer).
#include "mesh_io/mesh_io.hpp"
#include "preview/preview.hpp"
#include "viewer/viewer.hpp"

#include "capture/capture_set.hpp"

#include <getopt.h>
#include <signal.h>
#include <sys/stat.h>

#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace facescan::cli {

static void view_usage(FILE *out)
{
	std::fprintf(out, "usage: facescan view [DIR|MESH.glb] [--port N] [--bind ADDR]\n"
			  "\n"
			  "Serves the web viewer: DIR is a share (<patient>/<scan>.glb ...; default the\n"
			  "current directory), MESH one scan. Listens on 127.0.0.1:N (default 8080; 0 = any\n"
			  "free port) unless --bind says otherwise, prints the URL, serves until stopped.\n"
			  "Only the share's scan files are served; paths leaving it are refused.\n");
}

int view_main(int argc, char **argv)
{
	static const option opts[] = {{"port", required_argument, nullptr, 'p'},
				      {"bind", required_argument, nullptr, 'b'},
				      {"help", no_argument, nullptr, 'h'},
				      {nullptr, 0, nullptr, 0}};
	viewer::Options o;
	optind = 1;
	for (int opt; (opt = getopt_long(argc, argv, "h", opts, nullptr)) != -1;) {
		if (opt == 'h') {
			view_usage(stdout);
			return 0;
		}
		if (opt == 'p') {
			char *end = nullptr;
			o.port = int(std::strtol(optarg, &end, 10));
			if (!*optarg || *end || o.port < 0 || o.port > 65535) {
				std::fprintf(stderr, "facescan view: --port must be 0..65535\n");
				return 2;
			}
		} else if (opt == 'b') {
			o.bind = optarg;
		} else {
			view_usage(stderr);
			return 2;
		}
	}
	if (optind + 1 < argc) {
		view_usage(stderr);
		return 2;
	}
	const std::string target = optind < argc ? argv[optind] : ".";
	struct stat st;
	if (stat(target.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
		o.share_dir = target;
	else
		o.single_mesh = target;
	Status s = viewer::find_web_dir(&o.web_dir);
	// Stop on SIGINT/SIGTERM by waiting for them here instead of dying inside a handler.
	sigset_t set;
	sigemptyset(&set);
	sigaddset(&set, SIGINT);
	sigaddset(&set, SIGTERM);
	pthread_sigmask(SIG_BLOCK, &set, nullptr); // before the server thread exists: it inherits
	viewer::Server server;
	int port = 0;
	if (s.ok())
		s = server.start(o, &port);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan view: %s\n", s.message().c_str());
		return 1;
	}
	const std::string host = o.bind == "0.0.0.0" ? "localhost" : o.bind;
	if (o.single_mesh.empty())
		std::printf("facescan view: http://%s:%d/\n", host.c_str(), port);
	else
		std::printf("facescan view: http://%s:%d/view.html?mesh=/share/%s\n", host.c_str(), port,
			    o.single_mesh.substr(o.single_mesh.rfind('/') + 1).c_str());
	std::fflush(stdout);
	int sig = 0;
	sigwait(&set, &sig);
	server.stop();
	return 0;
}

int thumbnail_main(int argc, char **argv)
{
	static const option opts[] = {{"azimuth", required_argument, nullptr, 'a'},
				      {"size", required_argument, nullptr, 's'},
				      {"mask", no_argument, nullptr, 'm'},
				      {"help", no_argument, nullptr, 'h'},
				      {nullptr, 0, nullptr, 0}};
	std::vector<double> azimuths;
	int w = 320, h = 400;
	bool mask = false;
	optind = 1;
	for (int opt; (opt = getopt_long(argc, argv, "h", opts, nullptr)) != -1;) {
		switch (opt) {
		case 'a': azimuths.push_back(std::atof(optarg)); break;
		case 's':
			if (std::sscanf(optarg, "%dx%d", &w, &h) != 2 || w < 1 || h < 1 || w > 8192 || h > 8192) {
				std::fprintf(stderr, "facescan thumbnail: --size must be WxH (1..8192)\n");
				return 2;
			}
			break;
		case 'm': mask = true; break;
		case 'h':
			std::printf("usage: facescan thumbnail MESH OUT.png [--azimuth DEG] [--size WxH] [--mask]\n"
				    "\nRenders MESH with the project's ray caster as the viewer frames it: without\n"
				    "--azimuth the scan thumbnail (-45, 0, +45 degrees side by side), with it one\n"
				    "view; --mask writes the silhouette (255 = mesh) instead of the picture.\n");
			return 0;
		default: return 2;
		}
	}
	if (optind + 2 != argc) {
		std::fprintf(stderr, "facescan thumbnail: need MESH and OUT.png\n");
		return 2;
	}
	recon::Mesh mesh;
	Status s = mesh_io::read_mesh(argv[optind], mesh_io::Units::mm, "", &mesh);
	cv::Mat img, m;
	if (s.ok() && azimuths.empty() && !mask)
		s = preview::thumbnail(mesh, w, h, &img);
	else if (s.ok())
		s = preview::render(mesh, preview::frame_mesh(mesh, azimuths.empty() ? 0 : azimuths[0], w, h), &img, &m);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan thumbnail: %s\n", s.message().c_str());
		return 1;
	}
	std::vector<unsigned char> png;
	if (!cv::imencode(".png", mask ? m : img, png)) {
		std::fprintf(stderr, "facescan thumbnail: PNG encoding failed\n");
		return 1;
	}
	s = write_file_atomic(argv[optind + 1], png.data(), png.size());
	if (!s.ok()) {
		std::fprintf(stderr, "facescan thumbnail: %s\n", s.message().c_str());
		return 1;
	}
	return 0;
}

} // namespace facescan::cli
