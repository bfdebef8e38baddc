// facescan simulate: renders a capture set of the simulated booth.
#include "sim/sim.hpp"

#include <opencv2/imgproc.hpp>

#include <getopt.h>
#include <sys/stat.h>

#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace facescan::cli {

static void simulate_usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan simulate [--scene NAME] [--config FILE] [--seed N] [--head-seed N|canonical]\n"
		     "                         [--scale S] [--supersample N] [--no-texture]\n"
		     "                         [--contact-sheet PNG]\n"
		     "                         --out DIR\n"
		     "\n"
		     "Renders the booth (4 cameras, 3 projectors throwing the pattern slide) looking at\n"
		     "a procedural head and writes a capture set: DIR/cam{i}.png, cam{i}_texture.png,\n"
		     "calibration.yaml, capture.json, ground_truth.ply (docs/simulator.md).\n"
		     "  --scene NAME       default | turned | noisy | dark (default: default)\n"
		     "  --config FILE      rig file (default: built-in, = tools/sim/rigs/default.yaml)\n"
		     "  --seed N           sensor noise seed (default 1); same seeds, same images\n"
		     "  --head-seed N      draws the head's anatomy (default: the --seed value);\n"
		     "                     'canonical' keeps the fixed reference head\n"
		     "  --scale S          camera resolution factor, K scaled to match (0 < S <= 4)\n"
		     "  --supersample N    N x N rays per pixel (default: the rig's)\n"
		     "  --no-texture       skip the texture frames\n"
		     "  --contact-sheet P  also write a contact sheet (pattern + texture frames) to P\n");
}

static int bad(const char *what, const char *value)
{
	std::fprintf(stderr, "facescan simulate: %s, got '%s'\n", what, value);
	return 2;
}

int simulate_main(int argc, char **argv)
{
	static const option options[] = {{"scene", required_argument, nullptr, 's'},
					 {"config", required_argument, nullptr, 'c'},
					 {"seed", required_argument, nullptr, 'S'},
					 {"head-seed", required_argument, nullptr, 'H'},
					 {"scale", required_argument, nullptr, 'x'},
					 {"supersample", required_argument, nullptr, 'a'},
					 {"no-texture", no_argument, nullptr, 'n'},
					 {"contact-sheet", required_argument, nullptr, 'k'},
					 {"out", required_argument, nullptr, 'o'},
					 {"help", no_argument, nullptr, 'h'},
					 {nullptr, 0, nullptr, 0}};
	std::string scene_name = "default", config, out, sheet;
	unsigned long long seed = 1, head_seed = 0;
	bool head_seed_given = false, canonical_head = false;
	double scale = 1;
	int supersample = 0;
	bool texture = true;
	optind = 1;
	for (int opt; (opt = getopt_long(argc, argv, "s:c:S:H:x:a:nk:o:h", options, nullptr)) != -1;) {
		char *end = nullptr;
		switch (opt) {
		case 's':
			scene_name = optarg;
			break;
		case 'c':
			config = optarg;
			break;
		case 'S':
			errno = 0;
			seed = std::strtoull(optarg, &end, 10);
			if (!*optarg || *end || errno || optarg[0] == '-')
				return bad("--seed must be a non-negative integer", optarg);
			break;
		case 'H':
			head_seed_given = true;
			canonical_head = std::strcmp(optarg, "canonical") == 0;
			if (canonical_head)
				break;
			errno = 0;
			head_seed = std::strtoull(optarg, &end, 10);
			if (!*optarg || *end || errno || optarg[0] == '-')
				return bad("--head-seed must be a non-negative integer or 'canonical'", optarg);
			break;
		case 'x':
			scale = std::strtod(optarg, &end);
			if (!*optarg || *end || !(scale > 0 && scale <= 4))
				return bad("--scale must be in (0, 4]", optarg);
			break;
		case 'a': {
			long v = std::strtol(optarg, &end, 10);
			if (!*optarg || *end || v < 1 || v > 8)
				return bad("--supersample must be 1..8", optarg);
			supersample = int(v);
			break;
		}
		case 'n':
			texture = false;
			break;
		case 'k':
			sheet = optarg;
			break;
		case 'o':
			out = optarg;
			break;
		case 'h':
			simulate_usage(stdout);
			return 0;
		default:
			simulate_usage(stderr);
			return 2;
		}
	}
	if (optind != argc || out.empty()) {
		std::fprintf(stderr, "facescan simulate: %s\n",
			     out.empty() ? "--out DIR is required" : "unexpected argument");
		simulate_usage(stderr);
		return 2;
	}
	sim::Scene scene;
	Status st = sim::scene_by_name(scene_name, &scene);
	if (!st.ok()) {
		std::fprintf(stderr, "facescan simulate: %s\n", st.message().c_str());
		return 2;
	}
	if (!head_seed_given)
		head_seed = seed;
	if (!canonical_head)
		scene.head.shape = sim::random_head_shape(head_seed);
	const std::string head_desc = canonical_head ? "canonical" : "seed " + std::to_string(head_seed);
	sim::Rig rig = sim::default_rig();
	if (!config.empty())
		st = sim::load_rig(config, &rig);
	if (st.ok() && scale != 1)
		st = sim::scale_rig(scale, &rig);
	if (!st.ok()) {
		std::fprintf(stderr, "facescan simulate: %s\n", st.message().c_str());
		return 1;
	}
	if (supersample)
		rig.supersample = supersample;
	Pattern pattern;
	SlideSpec slide;
	if (!rig.projectors.empty())
		slide.width = rig.projectors[0].size.width, slide.height = rig.projectors[0].size.height;
	st = default_pattern(slide, &pattern);
	if (!st.ok()) {
		std::fprintf(stderr, "facescan simulate: pattern: %s\n", st.message().c_str());
		return 1;
	}
	sim::SimOptions so;
	so.texture_frames = texture;
	CaptureSet set;
	sim::SimTruth truth;
	std::clock_t cpu0 = std::clock();
	st = sim::simulate(rig, scene, pattern, seed, &set, &truth, so);
	double cpu = double(std::clock() - cpu0) / CLOCKS_PER_SEC;
	if (!st.ok()) {
		std::fprintf(stderr, "facescan simulate: %s\n", st.message().c_str());
		return 1;
	}
	auto t0 = std::chrono::steady_clock::now();
	if (mkdir(out.c_str(), 0755) < 0 && errno != EEXIST) {
		std::fprintf(stderr, "facescan simulate: cannot create %s: %s\n", out.c_str(),
			     std::strerror(errno));
		return 1;
	}
	st = sim::write_simulated_set(out, set, truth);
	if (st.ok() && !sheet.empty())
		st = write_image_atomic(sheet, sim::contact_sheet(set, 360));
	if (!st.ok()) {
		std::fprintf(stderr, "facescan simulate: %s\n", st.message().c_str());
		return 1;
	}
	double wsecs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
	std::printf("simulate: scene %s, seed %llu, head %s, %zu cameras %dx%d, %zu projectors, pattern %s\n"
		    "simulate: head %zu triangles; rendered %zu pattern + %zu texture frames in %.2f s"
		    " (%.2f s CPU; writing %.2f s) -> %s\n",
		    scene.name.c_str(), seed, head_desc.c_str(), rig.cameras.size(), rig.cameras[0].model.size.width,
		    rig.cameras[0].model.size.height, rig.projectors.size(), pattern.id.c_str(),
		    truth.head.triangles.size(), set.frames.size(), set.textures.size(),
		    truth.render_seconds, cpu, wsecs, out.c_str());
	return 0;
}

} // namespace facescan::cli
