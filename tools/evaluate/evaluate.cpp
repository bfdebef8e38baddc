// facescan evaluate: accuracy of a reconstructed mesh against a simulated capture set's truth.
#include "capture/capture_set.hpp"
#include "eval/eval.hpp"
#include "facescan/outputs.hpp"
#include "mesh_io/mesh_io.hpp"
#include "sim/sim.hpp"

#include <nlohmann/json.hpp>

#include <getopt.h>

#include <cstdio>
#include <cstdlib>
#include <string>

namespace facescan::cli {

static void evaluate_usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan evaluate MESH CAPTURE_DIR [--rig FILE] [--json OUT.json]\n"
		     "\n"
		     "Compares MESH (.drc or .ply, mm) with CAPTURE_DIR/ground_truth.ply (a simulated\n"
		     "capture set): distance of every distinct mesh vertex position (a texture seam's\n"
		     "duplicates count once) to the true surface (RMS, median, p95,\n"
		     "max, mm) and completeness: the fraction of true surface points seen by >= 2 cameras\n"
		     "and lit by a projector (through its slide mask, where the set records one) that\n"
		     "lie within 1 mm of the mesh. Where the set has ground_truth_face.ply (the face:\n"
		     "hairline to chin, ear to ear), the same figures over the face's truth points:\n"
		     "face completeness, how many face points the booth counts, and the distinct vertex\n"
		     "positions within ~2 mm of a face point (the issue's floors are over these).\n"
		     "No output may name the mesh, a file of the set or of\n"
		     "--recon-debug, or another output, and each must end in its extension (exit 2).\n"
		     "  --rig FILE       the simulator rig the set was rendered with (projector poses);\n"
		     "                   default: CAPTURE_DIR/ground_truth_projectors.yaml (written by\n"
		     "                   facescan simulate), else the built-in default rig\n"
		     "  --within MM      completeness distance (default 1 mm)\n"
		     "  --json OUT.json  also write the numbers as JSON\n"
		     "  --errors OUT.ply the reconstruction coloured by each vertex's distance to the\n"
		     "                   truth: green <= 0.3 mm, yellow <= 0.6, orange <= 1, red <= 2,\n"
		     "                   magenta beyond (where the RMS comes from)\n"
		     "  --coverage OUT.ply  the truth mesh coloured by completeness: green covered,\n"
		     "                   red missed, grey not counted (seen by < 2 cameras or unlit)\n"
		     "  --missing OUT.ply  with --recon-debug DIR (facescan recon --debug DIR of MESH):\n"
		     "                   where each missed truth point went, over the pairs whose two\n"
		     "                   cameras see it (the furthest any got): printed as a table, and\n"
		     "                   the truth mesh coloured by it (docs/recon.md, Limits)\n"
		     "  --report R.json  the recon report of MESH (facescan recon --report), and\n"
		     "  --markdown NAME  print one row of docs/benchmarks.md's table for it instead\n");
}

int evaluate_main(int argc, char **argv)
{
	static const option options[] = {{"rig", required_argument, nullptr, 'r'},
					 {"json", required_argument, nullptr, 'j'},
					 {"within", required_argument, nullptr, 'w'},
					 {"report", required_argument, nullptr, 'R'},
					 {"markdown", required_argument, nullptr, 'm'},
					 {"coverage", required_argument, nullptr, 'c'},
					 {"errors", required_argument, nullptr, 'e'},
					 {"missing", required_argument, nullptr, 'M'},
					 {"recon-debug", required_argument, nullptr, 'D'},
					 {"help", no_argument, nullptr, 'h'},
					 {nullptr, 0, nullptr, 0}};
	std::string rig_path, json_path, report_path, row_name, coverage_path, errors_path, missing_path,
		recon_debug;
	eval::EvalParams params;
	optind = 1;
	for (int opt; (opt = getopt_long(argc, argv, "h", options, nullptr)) != -1;) {
		switch (opt) {
		case 'r':
			rig_path = optarg;
			break;
		case 'j':
			json_path = optarg;
			break;
		case 'R':
			report_path = optarg;
			break;
		case 'm':
			row_name = optarg;
			break;
		case 'c':
			coverage_path = optarg;
			break;
		case 'e':
			errors_path = optarg;
			break;
		case 'M':
			missing_path = optarg;
			break;
		case 'D':
			recon_debug = optarg;
			break;
		case 'w': {
			char *end = nullptr;
			params.completeness_mm = std::strtod(optarg, &end);
			if (!*optarg || *end || !(params.completeness_mm > 0)) {
				std::fprintf(stderr, "facescan evaluate: --within must be a positive number of mm\n");
				return 2;
			}
			break;
		}
		case 'h':
			evaluate_usage(stdout);
			return 0;
		default:
			evaluate_usage(stderr);
			return 2;
		}
	}
	if (optind + 2 != argc) {
		std::fprintf(stderr, "facescan evaluate: need MESH and CAPTURE_DIR\n");
		evaluate_usage(stderr);
		return 2;
	}
	if (missing_path.empty() != recon_debug.empty()) {
		std::fprintf(stderr, "facescan evaluate: --missing and --recon-debug go together\n");
		return 2;
	}
	const std::string mesh_path = argv[optind], dir = argv[optind + 1];
	// What evaluate reads stays as it was: no output may name an input or another output.
	std::vector<InputFile> inputs = capture_set_inputs(dir);
	inputs.push_back({mesh_path, "the mesh being evaluated"});
	if (!rig_path.empty())
		inputs.push_back({rig_path, "the rig (--rig)"});
	if (!report_path.empty())
		inputs.push_back({report_path, "the recon report (--report)"});
	if (!recon_debug.empty())
		for (InputFile &f : directory_inputs(recon_debug, "in the recon debug directory (--recon-debug)"))
			inputs.push_back(std::move(f));
	std::string why;
	if (!check_outputs(inputs,
			   {{json_path, ".json"}, {errors_path, ".ply"}, {coverage_path, ".ply"}, {missing_path, ".ply"}},
			   &why)) {
		std::fprintf(stderr, "facescan evaluate: %s\n", why.c_str());
		return 2;
	}
	recon::Mesh mesh, truth;
	const bool drc = mesh_path.size() > 4 && mesh_path.compare(mesh_path.size() - 4, 4, ".drc") == 0;
	Status s = drc ? mesh_io::read_draco(mesh_path, &mesh) : mesh_io::read_ply(mesh_path, &mesh);
	// Which points were lit: the projectors the set records (written by the simulator), else
	// the rig named, else the built-in default rig.
	std::vector<CameraModel> projectors;
	if (s.ok())
		s = eval::read_ground_truth(dir, &truth, &projectors, &params.projector_masks, &params.truth_face);
	Calibration cal;
	if (s.ok())
		s = read_calibration(dir + "/calibration.yaml", &cal);
	if (s.ok() && (projectors.empty() || !rig_path.empty())) {
		sim::Rig rig = sim::default_rig();
		if (!rig_path.empty())
			s = sim::load_rig(rig_path, &rig);
		projectors = sim::projector_models(rig);
		params.projector_masks = sim::projector_masks(rig);
	}
	if (!s.ok()) {
		std::fprintf(stderr, "facescan evaluate: %s\n", s.message().c_str());
		return 1;
	}
	eval::EvalResult r;
	s = eval::evaluate(mesh, truth, cal.cameras, projectors, params, &r);
	if (!s.ok()) {
		std::fprintf(stderr, "facescan evaluate: %s\n", s.message().c_str());
		return 1;
	}
	if (!errors_path.empty()) {
		// Where the RMS comes from: each vertex by its distance to the truth (BGR colours).
		recon::Mesh coloured;
		coloured.positions = mesh.positions;
		coloured.triangles = mesh.triangles;
		coloured.normals = mesh.normals;
		coloured.colours.resize(mesh.positions.size());
		for (size_t i = 0; i < mesh.positions.size(); ++i) {
			const float e = r.vertex_mm[i];
			coloured.colours[i] = e <= 0.3f ? cv::Vec3b(60, 200, 60)
					      : e <= 0.6f ? cv::Vec3b(40, 220, 220)
					      : e <= 1.0f ? cv::Vec3b(30, 140, 250)
					      : e <= 2.0f ? cv::Vec3b(40, 40, 230)
							  : cv::Vec3b(230, 40, 230);
		}
		s = mesh_io::write_ply(errors_path, coloured);
		if (!s.ok()) {
			std::fprintf(stderr, "facescan evaluate: %s\n", s.message().c_str());
			return 1;
		}
	}
	if (!coverage_path.empty()) {
		// Where completeness is lost, to look at in a mesh viewer (BGR colours).
		truth.colours.resize(truth.positions.size());
		for (size_t i = 0; i < truth.positions.size(); ++i)
			truth.colours[i] = r.truth_status[i] < 0 ? cv::Vec3b(160, 160, 160)
					   : r.truth_status[i]	 ? cv::Vec3b(60, 200, 60)
								 : cv::Vec3b(40, 40, 230);
		truth.uvs.clear();
		truth.texture.release();
		s = mesh_io::write_ply(coverage_path, truth);
		if (!s.ok()) {
			std::fprintf(stderr, "facescan evaluate: %s\n", s.message().c_str());
			return 1;
		}
	}
	if (!missing_path.empty()) {
		std::vector<eval::PairTrace> traces;
		s = eval::read_pair_traces(recon_debug, &traces);
		if (!s.ok()) {
			std::fprintf(stderr, "facescan evaluate: %s\n", s.message().c_str());
			return 1;
		}
		const std::vector<signed char> why = eval::attribute_missing(truth, r, cal.cameras, traces, params);
		// One colour per reason (BGR); grey: counted and covered or not counted.
		static const cv::Vec3b colours[eval::kMissReasons] = {
			{255, 255, 255}, {0, 0, 0},	{90, 90, 90},	 {40, 40, 230}, {120, 60, 60},
			{230, 40, 230},	 {0, 128, 255}, {0, 200, 255},	 {200, 120, 0}, {255, 0, 0},
			{0, 255, 128},	 {128, 0, 128}, {0, 255, 255},	 {255, 255, 0}};
		std::vector<int> count(eval::kMissReasons, 0);
		int missed = 0;
		truth.colours.assign(truth.positions.size(), cv::Vec3b(200, 200, 200));
		for (size_t i = 0; i < why.size(); ++i)
			if (why[i] >= 0 && why[i] < eval::kMissReasons) {
				count[size_t(why[i])]++;
				missed++;
				truth.colours[i] = colours[size_t(why[i])];
			}
		std::printf("missed %d of %d counted truth points, by where they went:\n", missed, r.truth_counted);
		for (int k = 0; k < eval::kMissReasons; ++k)
			std::printf("  %-20s %7d  %5.1f %% of missed  %5.2f %% of counted\n", eval::miss_reason_name(k),
				    count[size_t(k)], missed ? 100.0 * count[size_t(k)] / missed : 0.0,
				    r.truth_counted ? 100.0 * count[size_t(k)] / r.truth_counted : 0.0);
		recon::Mesh coloured;
		coloured.positions = truth.positions;
		coloured.triangles = truth.triangles;
		coloured.colours = truth.colours;
		s = mesh_io::write_ply(missing_path, coloured);
		if (!s.ok()) {
			std::fprintf(stderr, "facescan evaluate: %s\n", s.message().c_str());
			return 1;
		}
	}
	if (!row_name.empty()) {
		std::string text;
		s = mesh_io::read_file_bytes(report_path, &text);
		nlohmann::json rep = nlohmann::json::parse(text, nullptr, false);
		if (!s.ok() || rep.is_discarded() || !rep.is_object()) {
			std::fprintf(stderr, "facescan evaluate: --report '%s': %s\n", report_path.c_str(),
				     s.ok() ? "not a recon report" : s.message().c_str());
			return 1;
		}
		const nlohmann::json t = rep.value("time_ms", nlohmann::json::object());
		auto ms = [&t](const char *k) { return t.value(k, 0.0); };
		double d_before = 0, d_after = 0;
		for (const auto &reg : rep.value("registration", nlohmann::json::array())) {
			d_before = std::max(d_before, reg.value("D_before_mm2", 0.0));
			d_after = std::max(d_after, reg.value("D_after_mm2", 0.0));
		}
		std::printf("| %s | %.3f | %.3f | %.3f | %.1f %% | %d | %d | %.1fx | %.4f / %.4f | "
			    "%.0f / %.0f / %.0f / %.0f / %.0f / %.0f / %.0f | **%.0f** | %.0f |\n",
			    row_name.c_str(), r.rms_mm, r.median_mm, r.p95_mm, 100.0 * r.completeness,
			    r.vertices, r.triangles, rep.value("corner_multiplier", 0.0), d_before, d_after,
			    ms("detect"), ms("match"), ms("triangulate"), ms("mesh"), ms("register"), ms("fuse"),
			    ms("texture"), ms("total"), rep.value("peak_rss_kb", 0.0) / 1024.0);
		return 0;
	}
	std::printf("vertices %d, triangles %d\n", r.vertices, r.triangles);
	std::printf("vertex-to-surface: RMS %.3f mm, median %.3f mm, p95 %.3f mm, max %.3f mm\n", r.rms_mm,
		    r.median_mm, r.p95_mm, r.max_mm);
	std::printf("completeness: %.1f %% of %d truth points (seen by >= 2 cameras and lit) within %.2f mm; "
		    "%d vertices near them (whole head)\n",
		    100.0 * r.completeness, r.truth_counted, params.completeness_mm, r.face_vertices);
	if (r.face_truth_points > 0)
		std::printf("face completeness: %.1f %% of %d counted face points within %.2f mm; the booth counts "
			    "%d of the face's %d (%.1f %%); %d vertices on the face\n",
			    100.0 * r.face_completeness, r.face_counted, params.completeness_mm, r.face_counted,
			    r.face_truth_points, 100.0 * r.face_counted / r.face_truth_points, r.face_region_vertices);
	else
		std::printf("face: none (the set has no ground_truth_face.ply: rendered before simulate wrote it)\n");
	if (!json_path.empty()) {
		nlohmann::json j = {{"vertices", r.vertices},	   {"face_vertices", r.face_vertices},	   {"triangles", r.triangles},
				    {"unique_positions", r.unique_positions},
				    {"rms_mm", r.rms_mm},		   {"median_mm", r.median_mm},
				    {"p95_mm", r.p95_mm},		   {"max_mm", r.max_mm},
				    {"completeness", r.completeness}, {"truth_points", r.truth_points},
				    {"truth_counted", r.truth_counted}};
		// The face figures only where the set has a face (absent keys: an older set).
		if (r.face_truth_points > 0) {
			j["face_completeness"] = r.face_completeness;
			j["face_counted"] = r.face_counted;
			j["face_truth_points"] = r.face_truth_points;
			j["face_region_vertices"] = r.face_region_vertices;
		}
		const std::string text = j.dump(2) + "\n";
		s = write_file_atomic(json_path, text.data(), text.size());
		if (!s.ok()) {
			std::fprintf(stderr, "facescan evaluate: %s\n", s.message().c_str());
			return 1;
		}
	}
	return 0;
}

} // namespace facescan::cli
