// facescan recon: capture set → Draco face mesh (+ texture PNG, optional PLY and JSON report).
#include "capture/capture_set.hpp"
#include "mesh_io/mesh_io.hpp"
#include "pattern/pattern.hpp"
#include "recon/pipeline.hpp"

#include <opencv2/imgcodecs.hpp>

#include <getopt.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <string>
#include <vector>

namespace facescan::cli {

static void recon_usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan recon CAPTURE_DIR -o OUT.drc [--ply OUT.ply] [--report OUT.json]\n"
		     "                      [--no-texture]\n"
		     "\n"
		     "Reconstructs the face of a capture set (docs/capture-format.md) and writes it as a\n"
		     "Draco mesh (positions in mm in the calibration's world frame, UVs, normals), the\n"
		     "texture atlas beside it (OUT.png), and optionally a PLY copy and a JSON report of\n"
		     "each stage's counts and timings (docs/recon.md). Every file is written atomically;\n"
		     "on any error nothing is written.\n"
		     "  -o, --out OUT.drc     the Draco mesh (required)\n"
		     "  --ply OUT.ply         also write a PLY (binary, with UVs or colours)\n"
		     "  --report OUT.json     write the stage report\n"
		     "  --no-texture          skip the texture stage\n");
}

static std::string texture_path(const std::string &drc)
{
	const size_t slash = drc.find_last_of('/');
	const size_t dot = drc.find_last_of('.');
	if (dot != std::string::npos && (slash == std::string::npos || dot > slash))
		return drc.substr(0, dot) + ".png";
	return drc + ".png";
}

int recon_main(int argc, char **argv)
{
	static const option options[] = {{"out", required_argument, nullptr, 'o'},
					 {"ply", required_argument, nullptr, 'p'},
					 {"report", required_argument, nullptr, 'r'},
					 {"no-texture", no_argument, nullptr, 'T'},
					 {"help", no_argument, nullptr, 'h'},
					 {nullptr, 0, nullptr, 0}};
	std::string out, ply, report_path;
	recon::ReconParams params;
	optind = 1;
	for (int opt; (opt = getopt_long(argc, argv, "o:h", options, nullptr)) != -1;) {
		switch (opt) {
		case 'o':
			out = optarg;
			break;
		case 'p':
			ply = optarg;
			break;
		case 'r':
			report_path = optarg;
			break;
		case 'T':
			params.texture_enabled = false;
			break;
		case 'h':
			recon_usage(stdout);
			return 0;
		default:
			recon_usage(stderr);
			return 2;
		}
	}
	if (optind + 1 != argc || out.empty()) {
		std::fprintf(stderr, "facescan recon: need one CAPTURE_DIR and -o OUT.drc\n");
		recon_usage(stderr);
		return 2;
	}
	const std::string dir = argv[optind];

	CaptureSet set;
	Status s = read_capture_set(dir, &set);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan recon: %s\n", s.message().c_str());
		return 1;
	}
	Pattern pattern;
	s = pattern_from_id(set.meta.pattern_id, SlideSpec(), &pattern);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan recon: %s/capture.json: pattern '%s': %s\n", dir.c_str(),
			     set.meta.pattern_id.c_str(), s.message().c_str());
		return 1;
	}
	recon::Mesh mesh;
	recon::ReconReport report;
	s = recon::reconstruct(set, pattern, params, &mesh, &report);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan recon: %s: %s\n", dir.c_str(), s.message().c_str());
		return 1;
	}

	// Encode everything in memory first, then write each file atomically; if a later write
	// fails, the earlier ones of this run are removed so no partial result is left.
	struct Output {
		std::string path;
		std::string bytes;
	};
	std::vector<Output> outputs;
	std::vector<char> drc;
	s = mesh_io::encode_draco(mesh, mesh_io::DracoOptions(), &drc);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan recon: %s: %s\n", out.c_str(), s.message().c_str());
		return 1;
	}
	outputs.push_back({out, std::string(drc.begin(), drc.end())});
	if (!mesh.texture.empty()) {
		std::vector<uchar> png;
		if (!cv::imencode(".png", mesh.texture, png)) {
			std::fprintf(stderr, "facescan recon: cannot encode the texture image\n");
			return 1;
		}
		outputs.push_back({texture_path(out), std::string(png.begin(), png.end())});
	}
	if (!ply.empty()) {
		std::string bytes;
		s = mesh_io::encode_ply(mesh, &bytes);
		if (!s.ok()) {
			std::fprintf(stderr, "facescan recon: %s: %s\n", ply.c_str(), s.message().c_str());
			return 1;
		}
		outputs.push_back({ply, bytes});
	}
	rusage ru {};
	if (getrusage(RUSAGE_SELF, &ru) == 0)
		report.peak_rss_kb = ru.ru_maxrss;
	if (!report_path.empty())
		outputs.push_back({report_path, recon::report_json(report)});
	for (size_t i = 0; i < outputs.size(); ++i) {
		s = write_file_atomic(outputs[i].path, outputs[i].bytes.data(), outputs[i].bytes.size());
		if (!s.ok()) {
			std::fprintf(stderr, "facescan recon: %s\n", s.message().c_str());
			for (size_t k = 0; k < i; ++k)
				unlink(outputs[k].path.c_str());
			return 1;
		}
	}
	double total = 0;
	for (const recon::StageTime &t : report.stages)
		if (t.name == "total")
			total = t.ms;
	std::printf("facescan recon: %s: %d vertices, %d triangles, corner multiplier %.1fx, %.0f ms\n",
		    out.c_str(), report.vertices, report.triangles, report.corner_multiplier, total);
	return 0;
}

} // namespace facescan::cli
