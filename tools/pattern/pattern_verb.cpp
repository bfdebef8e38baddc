// facescan pattern: writes the projector slide and pattern.json.
#include "capture/capture_set.hpp"
#include "pattern/pattern.hpp"

#include <getopt.h>
#include <sys/stat.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace facescan::cli {

static void pattern_usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan pattern [--width W] [--height H] [--gap F] [--id ID] --out DIR\n"
		     "\n"
		     "Writes DIR/slide.png (the slide a projector throws) and DIR/pattern.json\n"
		     "(id, matrix, per-cell rectangles on the slide).\n"
		     "  --width W, --height H   projector resolution (default 1024x768)\n"
		     "  --gap F                 black gap between squares, fraction of the pitch (0.30)\n"
		     "  --id ID                 regenerate a known pattern id instead of the default\n");
}

static bool parse_int(const char *s, int lo, int hi, int *ret)
{
	char *end = nullptr;
	long v = std::strtol(s, &end, 10);
	if (!*s || *end || v < lo || v > hi)
		return false;
	*ret = int(v);
	return true;
}

int pattern_main(int argc, char **argv)
{
	static const option options[] = {{"width", required_argument, nullptr, 'w'},
					 {"height", required_argument, nullptr, 'H'},
					 {"gap", required_argument, nullptr, 'g'},
					 {"id", required_argument, nullptr, 'i'},
					 {"out", required_argument, nullptr, 'o'},
					 {"help", no_argument, nullptr, 'h'},
					 {nullptr, 0, nullptr, 0}};
	SlideSpec slide;
	std::string out, id;
	optind = 1;
	for (int opt; (opt = getopt_long(argc, argv, "w:H:g:i:o:h", options, nullptr)) != -1;) {
		switch (opt) {
		case 'w':
			if (!parse_int(optarg, 64, 16384, &slide.width)) {
				std::fprintf(stderr, "facescan pattern: --width must be 64..16384, got '%s'\n", optarg);
				return 2;
			}
			break;
		case 'H':
			if (!parse_int(optarg, 64, 16384, &slide.height)) {
				std::fprintf(stderr, "facescan pattern: --height must be 64..16384, got '%s'\n", optarg);
				return 2;
			}
			break;
		case 'g': {
			char *end = nullptr;
			slide.gap_fraction = std::strtod(optarg, &end);
			if (!*optarg || *end || !(slide.gap_fraction >= 0 && slide.gap_fraction < 0.9)) {
				std::fprintf(stderr, "facescan pattern: --gap must be in [0, 0.9), got '%s'\n", optarg);
				return 2;
			}
			break;
		}
		case 'i':
			id = optarg;
			break;
		case 'o':
			out = optarg;
			break;
		case 'h':
			pattern_usage(stdout);
			return 0;
		default:
			pattern_usage(stderr);
			return 2;
		}
	}
	if (optind != argc || out.empty()) {
		std::fprintf(stderr, "facescan pattern: %s\n",
			     out.empty() ? "--out DIR is required" : "unexpected argument");
		pattern_usage(stderr);
		return 2;
	}
	Pattern pattern;
	Status st = id.empty() ? default_pattern(slide, &pattern) : pattern_from_id(id, slide, &pattern);
	if (!st.ok()) {
		std::fprintf(stderr, "facescan pattern: %s\n", st.message().c_str());
		return st.code() == -ENOENT ? 2 : 1;
	}
	if (mkdir(out.c_str(), 0755) < 0 && errno != EEXIST) {
		std::fprintf(stderr, "facescan pattern: cannot create %s: %s\n", out.c_str(), std::strerror(errno));
		return 1;
	}
	st = write_image_atomic(out + "/slide.png", render_slide(pattern));
	if (st.ok())
		st = write_pattern_json(out + "/pattern.json", pattern);
	if (!st.ok()) {
		std::fprintf(stderr, "facescan pattern: %s\n", st.message().c_str());
		return 1;
	}
	std::printf("pattern %s: %dx%d cells, %d decodable of %d code words, min Hamming distance %d\n"
		    "slide %dx%d, pitch %.2f px -> %s/slide.png, %s/pattern.json\n",
		    pattern.id.c_str(), pattern.matrix.rows(), pattern.matrix.cols(),
		    pattern.matrix.decodable_cells(), pattern.matrix.word_space(),
		    pattern.matrix.min_hamming_distance(), slide.width, slide.height, pattern.pitch,
		    out.c_str(), out.c_str());
	return 0;
}

} // namespace facescan::cli
