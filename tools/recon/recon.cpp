// facescan recon: capture set → Draco face mesh (+ texture PNG, optional PLY and JSON report).
#include "capture/capture_set.hpp"
#include "facescan/outputs.hpp"
#include "mesh_io/mesh_io.hpp"
#include "pattern/pattern.hpp"
#include "recon/pipeline.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <getopt.h>
#include <malloc.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

namespace facescan::cli {

namespace {

void recon_usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan recon CAPTURE_DIR -o OUT.drc [--ply OUT.ply] [--report OUT.json]\n"
		     "                      [--no-texture] [--sparse] [--debug DIR]\n"
		     "\n"
		     "Reconstructs the face of a capture set (docs/capture-format.md) and writes it as a\n"
		     "Draco mesh (positions in mm in the calibration's world frame, UVs, normals), the\n"
		     "texture atlas beside it (OUT.png), and optionally a PLY copy and a JSON report of\n"
		     "each stage's counts and timings (docs/recon.md). Every file is written atomically;\n"
		     "on any error nothing is written. No output may name a file of the capture set or\n"
		     "another output, and each must end in its extension (refused with exit 2).\n"
		     "  -o, --out OUT.drc     the Draco mesh (required)\n"
		     "  --ply OUT.ply         also write a PLY (binary, with UVs or colours)\n"
		     "  --report OUT.json     write the stage report\n"
		     "  --no-texture          skip the texture stage\n"
		     "  --sparse              the paper's sparse mesh only (no dense matching)\n"
		     "  --debug DIR           write overlays (squares, letters, cell ids, corners, matches,\n"
		     "                        dense prior and disparity) and the dense clouds into DIR,\n"
		     "                        also when the reconstruction fails\n");
}

static std::string texture_path(const std::string &drc)
{
	const size_t n = drc.size();
	return n > 4 && drc.compare(n - 4, 4, ".drc") == 0 ? drc.substr(0, n - 4) + ".png" : drc + ".png";
}

// What the operator must hear about a reconstruction that succeeded but is suspect. Warned,
// not refused: the mesh may still serve, and poor light or skin lowers the same figures.
static std::vector<std::string> report_warnings(const recon::ReconReport &r, const std::string &pattern_id)
{
	std::vector<std::string> out;
	long detected = 0, decoded = 0;
	for (const recon::CameraReport &c : r.cameras) {
		detected += c.detected;
		decoded += c.decoded;
	}
	// Measured on the default simulated scene: the projected pattern decodes 72-82 % of the
	// squares per camera; another valid pattern id 5-15 %; real skin in a foreign booth 21-50 %.
	if (detected > 0 && decoded * 5 < detected) {
		char buf[256];
		std::snprintf(buf, sizeof buf,
			      "only %ld of %ld squares (%.0f %%) decoded with pattern %s: if the projectors threw "
			      "another slide, capture.json names the wrong pattern and the mesh is incomplete",
			      decoded, detected, 100.0 * double(decoded) / double(detected), pattern_id.c_str());
		out.push_back(buf);
	}
	for (const recon::PairReport &p : r.pairs)
		if (!p.dense_error.empty())
			out.push_back("pair " + std::to_string(p.cam_a) + "-" + std::to_string(p.cam_b) +
				      ": dense stage failed (" + p.dense_error + "); the surface lacks that pair's view");
	bool any_match = false;
	for (const recon::PairReport &p : r.pairs)
		any_match = any_match || p.matches > 0;
	if (!any_match && r.dense)
		out.push_back("no pair has a code match: the surface rests on the dense search over the working "
			      "volume alone, with nothing from the code to check it against");
	for (const recon::CameraReport &c : r.cameras) {
		int matched = 0, dense_points = 0;
		std::string pairs;
		for (const recon::PairReport &p : r.pairs)
			if (p.cam_a == c.camera || p.cam_b == c.camera) {
				matched += p.matches;
				dense_points += p.dense.points;
				pairs += (pairs.empty() ? "" : ", ") + std::to_string(p.cam_a) + "-" + std::to_string(p.cam_b);
			}
		if (matched == 0)
			out.push_back("camera " + std::to_string(c.camera) + " has no seeds: " + std::to_string(c.decoded) +
				      " of " + std::to_string(c.detected) + " squares decoded, 0 matched in pair(s) " +
				      (pairs.empty() ? "none" : pairs) +
				      (r.dense ? "; searched over the working volume: " + std::to_string(dense_points) +
							 " dense points"
					       : std::string("; it contributes nothing")));
	}
	return out;
}

// Writes the debug overlays as DIR/<name>.png and the clouds as DIR/<name>.ply (colour =
// confidence). DIR is created when missing; it may not be the capture set's own directory.
Status write_debug(const std::string &debug_dir, const std::string &capture_dir, const recon::ReconDebug &debug)
{
	if (mkdir(debug_dir.c_str(), 0755) != 0 && errno != EEXIST)
		return Status::error(-errno, std::string("cannot create it: ") + std::strerror(errno));
	struct stat a {}, b {};
	if (stat(debug_dir.c_str(), &a) != 0 || !S_ISDIR(a.st_mode))
		return Status::error(-ENOTDIR, "not a directory");
	if (stat(capture_dir.c_str(), &b) == 0 && a.st_dev == b.st_dev && a.st_ino == b.st_ino)
		return Status::error(-EINVAL, "is the capture set's directory; debug output goes elsewhere");
	for (const recon::DebugImage &im : debug.images) {
		std::vector<uchar> png;
		if (im.image.empty() || !cv::imencode(".png", im.image, png))
			return Status::error(-EIO, "cannot encode " + im.name);
		Status s = write_file_atomic(debug_dir + "/" + im.name + ".png", png.data(), png.size());
		if (!s.ok())
			return s;
	}
	for (const recon::DebugText &t : debug.texts) {
		Status s = write_file_atomic(debug_dir + "/" + t.name, t.text.data(), t.text.size());
		if (!s.ok())
			return s;
	}
	for (const recon::DebugCloud &c : debug.clouds) {
		recon::Mesh m;
		m.positions = c.points;
		m.colours.reserve(c.points.size());
		for (size_t i = 0; i < c.points.size(); ++i) {
			const float v = i < c.value.size() ? std::clamp(c.value[i], 0.f, 1.f) : 1.f;
			m.colours.emplace_back(uchar(255 * v), uchar(255 * v), uchar(255 * (1 - v)));
		}
		std::string bytes;
		Status s = mesh_io::encode_ply(m, &bytes);
		if (s.ok())
			s = write_file_atomic(debug_dir + "/" + c.name + ".ply", bytes.data(), bytes.size());
		if (!s.ok())
			return s;
	}
	return {};
}

} // namespace

int recon_main(int argc, char **argv)
{
	static const option options[] = {{"out", required_argument, nullptr, 'o'},
					 {"ply", required_argument, nullptr, 'p'},
					 {"report", required_argument, nullptr, 'r'},
					 {"no-texture", no_argument, nullptr, 'T'},
					 {"sparse", no_argument, nullptr, 'S'},
					 {"debug", required_argument, nullptr, 'D'},
					 {"help", no_argument, nullptr, 'h'},
					 {nullptr, 0, nullptr, 0}};
	std::string out, ply, report_path, debug_dir;
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
		case 'S':
			params.dense_enabled = false;
			break;
		case 'D':
			debug_dir = optarg;
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
	// Checked before anything is read or computed, so a wrong name costs nothing and loses nothing.
	std::vector<std::pair<std::string, const char *>> outs = {
		{out, ".drc"}, {params.texture_enabled ? texture_path(out) : "", ".png"}, {ply, ".ply"}, {report_path, ".json"}};
	std::string why;
	if (!check_outputs(capture_set_inputs(dir), outs, &why)) {
		std::fprintf(stderr, "facescan recon: %s\n", why.c_str());
		return 2;
	}

	// The stages allocate and free many frame-sized images (cv::Mat temporaries of 2-8 MB).
	// Above glibc's dynamic mmap threshold each is a fresh mapping whose pages the kernel faults
	// in and zeroes again: bench booth 105 took 140k page faults and 0.3 s of system time.
	// Kept in the heap (up to the 32 MB ceiling mallopt allows), freed images are reused: 58k
	// faults, ~0.2 CPU s less, peak memory 258 -> 293 MB. One arena: the worker threads' own
	// arenas fault their pages in again (86k faults with the pairs' dense matching concurrent,
	// 58k in one), and two or three threads hardly contend for it.
	mallopt(M_MMAP_THRESHOLD, 32 << 20);
	mallopt(M_TRIM_THRESHOLD, 256 << 20);
	mallopt(M_ARENA_MAX, 1);
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
	recon::ReconDebug debug;
	s = recon::reconstruct(set, pattern, params, &mesh, &report, debug_dir.empty() ? nullptr : &debug);
	// The overlays are written also (and above all) when the reconstruction failed.
	if (!debug_dir.empty()) {
		const Status ds = write_debug(debug_dir, dir, debug);
		if (!ds.ok())
			std::fprintf(stderr, "facescan recon: --debug %s: %s\n", debug_dir.c_str(), ds.message().c_str());
	}
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
	// The atlas PNG is encoded on a second thread while Draco encodes the mesh: two independent,
	// single-threaded encoders of about the same length.
	std::vector<uchar> png;
	bool png_ok = true;
	std::thread png_encoder;
	if (!mesh.texture.empty())
		png_encoder = std::thread([&] {
			try {
				png_ok = cv::imencode(".png", mesh.texture, png);
			} catch (const cv::Exception &) {
				png_ok = false;
			}
		});
	s = mesh_io::encode_draco(mesh, mesh_io::DracoOptions(), &drc);
	if (png_encoder.joinable())
		png_encoder.join();
	if (!s.ok()) {
		std::fprintf(stderr, "facescan recon: %s: %s\n", out.c_str(), s.message().c_str());
		return 1;
	}
	outputs.push_back({out, std::string(drc.begin(), drc.end())});
	if (!mesh.texture.empty()) {
		if (!png_ok) {
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
	const std::vector<std::string> warnings = report_warnings(report, set.meta.pattern_id);
	if (!report_path.empty()) {
		nlohmann::json j = nlohmann::json::parse(recon::report_json(report), nullptr, false);
		if (j.is_object()) {
			j["warnings"] = warnings;
			outputs.push_back({report_path, j.dump(1) + "\n"});
		} else {
			outputs.push_back({report_path, recon::report_json(report)});
		}
	}
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
	for (const std::string &w : warnings)
		std::fprintf(stderr, "facescan recon: warning: %s\n", w.c_str());
	std::printf("facescan recon: %s: %d vertices, %d triangles, corner multiplier %.1fx, %.0f ms\n",
		    out.c_str(), report.vertices, report.triangles, report.corner_multiplier, total);
	return 0;
}

} // namespace facescan::cli
