// facescan — one CLI with git-style verbs: `facescan <verb> [options]`.
#include "verbs.hpp"
#include "common/version.hpp"

#include <cstdio>
#include <cstring>
#include <iterator>

using facescan::cli::Verb;

// One line per verb; the implementation stays with the component it drives.
namespace facescan::cli {
int pattern_main(int argc, char **argv);
int scan_main(int argc, char **argv);
int status_main(int argc, char **argv);
int last_main(int argc, char **argv);
int recon_main(int argc, char **argv);
int simulate_main(int argc, char **argv);
int evaluate_main(int argc, char **argv);
int calibrate_main(int argc, char **argv);
int convert_main(int argc, char **argv);
int dicom_main(int argc, char **argv);
int view_main(int argc, char **argv);
int thumbnail_main(int argc, char **argv);
} // namespace facescan::cli

static const Verb verbs[] = {
	{"version", "print the software version", nullptr},
	{"pattern", "generate the code matrix and the projector slide", facescan::cli::pattern_main},
	{"scan", "ask facescand for a scan of a patient and follow it", facescan::cli::scan_main},
	{"status", "what facescand is doing now", facescan::cli::status_main},
	{"last", "the outcome of the most recent scan", facescan::cli::last_main},
	{"recon", "reconstruct a capture set into a textured Draco face mesh", facescan::cli::recon_main},
	{"simulate", "render a capture set of the simulated booth", facescan::cli::simulate_main},
	{"evaluate", "compare a reconstructed mesh with a simulated set's ground truth", facescan::cli::evaluate_main},
	{"calibrate", "calibrate the cameras from images of a chessboard or ChArUco board", facescan::cli::calibrate_main},
	{"convert", "convert a mesh between .drc .ply .glb .obj .stl", facescan::cli::convert_main},
	{"dicom", "a mesh as a DICOM Encapsulated STL instance; C-STORE to the PACS", facescan::cli::dicom_main},
	{"view", "serve the web viewer for a share or one scan on localhost", facescan::cli::view_main},
	{"thumbnail", "render a mesh with the project's ray caster, framed as the viewer does", facescan::cli::thumbnail_main},
};

static void usage(FILE *out)
{
	std::fprintf(out, "usage: facescan <verb> [options]   (facescan <verb> --help for details)\n\n"
			  "verbs:\n");
	for (const Verb &v : verbs)
		std::fprintf(out, "  %-12s %s\n", v.name, v.summary);
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		usage(stderr);
		return 2;
	}
	const char *name = argv[1];
	if (!std::strcmp(name, "--help") || !std::strcmp(name, "-h") || !std::strcmp(name, "help")) {
		usage(stdout);
		return 0;
	}
	if (!std::strcmp(name, "version") || !std::strcmp(name, "--version")) {
		std::printf("facescan %s\n", facescan::version());
		return 0;
	}
	for (const Verb &v : verbs)
		if (v.main && !std::strcmp(name, v.name))
			return v.main(argc - 1, argv + 1);
	std::fprintf(stderr, "facescan: '%s' is not a verb (see facescan --help)\n", name);
	return 2;
}
