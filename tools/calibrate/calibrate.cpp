// facescan calibrate: images of a calibration target → calibration.yaml (docs/calibration.md).
// A thin CLI over host/calib: reads the images, lists the ones it skips, prints the report and
// writes the file atomically only when the calibration succeeded.
#include "calib/calib.hpp"
#include "capture/capture_set.hpp"
#include "facescan/outputs.hpp"

#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include <getopt.h>

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace facescan::cli {

int calibrate_main(int argc, char **argv);

namespace {

namespace fs = std::filesystem;

void usage(FILE *out)
{
	std::fprintf(out,
		     "usage: facescan calibrate (--pairs LIST | --dir DIR) --board COLSxROWS --square-mm S\n"
		     "                          -o OUT.yaml [options]\n"
		     "\n"
		     "Calibrates cameras from images of a chessboard or ChArUco board and writes the\n"
		     "capture set's calibration.yaml (docs/calibration.md).\n"
		     "\n"
		     "  --pairs LIST        two cameras: LIST has one 'left right' image pair per line,\n"
		     "                      paths relative to LIST ('#' starts a comment)\n"
		     "  --dir DIR           all cameras: DIR/pose<k>_cam<i>.<png|jpg|bmp|tif|pgm>, one\n"
		     "                      image per camera i for each board pose k\n"
		     "  --board COLSxROWS   inner corners of the board, e.g. 9x6\n"
		     "  --square-mm S       side of a square in mm\n"
		     "  --charuco           the board is a ChArUco board (default: chessboard)\n"
		     "  --marker-mm M       ChArUco marker side in mm\n"
		     "  --dict NAME         ChArUco dictionary (default DICT_5X5_1000)\n"
		     "  --detector NAME     chessboard detector: sb (findChessboardCornersSB, default)\n"
		     "                      or classic (findChessboardCorners + cornerSubPix)\n"
		     "  --origin WHERE      world frame: cam0 (default) or pose:K (the board in pose K)\n"
		     "  --min-views N       least board views per camera (default 4)\n"
		     "  --id NAME           calibration id recorded in the file\n"
		     "  -o, --output FILE   the calibration.yaml to write\n"
		     "  -h, --help          this help\n");
}

int bad_usage(const std::string &message)
{
	std::fprintf(stderr, "facescan calibrate: %s (see --help)\n", message.c_str());
	return 2;
}

int failure(const std::string &message)
{
	std::fprintf(stderr, "facescan calibrate: error: %s\n", message.c_str());
	return 1;
}

// images[pose][camera]: a path, or empty when that camera has no image of the pose.
using ImageTable = std::vector<std::vector<std::string>>;

constexpr size_t kMaxBoardImageBytes = size_t(256) << 20;

Status read_pairs(const std::string &list, ImageTable *ret)
{
	std::ifstream in(list);
	if (!in)
		return Status::error(ENOENT, "cannot open pair list " + list);
	const fs::path base = fs::path(list).parent_path();
	ImageTable table;
	std::string line;
	for (int n = 1; std::getline(in, line); n++) {
		const size_t hash = line.find('#');
		if (hash != std::string::npos)
			line.erase(hash);
		std::istringstream words(line);
		std::vector<std::string> paths;
		for (std::string w; words >> w;)
			paths.push_back(w);
		if (paths.empty())
			continue;
		if (paths.size() != 2)
			return Status::error(EINVAL, list + ":" + std::to_string(n) + ": want 'left right', got " +
							     std::to_string(paths.size()) + " path(s)");
		for (std::string &p : paths)
			if (fs::path(p).is_relative())
				p = (base / p).string();
		table.push_back(paths);
	}
	if (table.empty())
		return Status::error(EINVAL, list + ": no image pairs");
	*ret = std::move(table);
	return Status();
}

// "pose<k>_cam<i>.<image extension>" → k, i.
bool parse_image_name(const std::string &file, int *ret_pose, int *ret_cam)
{
	static const char *const exts[] = {"png", "jpg", "jpeg", "bmp", "tif", "tiff", "pgm", "ppm"};
	int pose = -1, cam = -1, used = 0;
	if (std::sscanf(file.c_str(), "pose%d_cam%d.%n", &pose, &cam, &used) != 2 || used == 0 ||
	    pose < 0 || cam < 0 || !std::isdigit((unsigned char)file[4]))
		return false;
	std::string ext = file.substr(size_t(used));
	for (char &ch : ext)
		ch = char(std::tolower((unsigned char)ch));
	for (const char *x : exts)
		if (ext == x) {
			*ret_pose = pose;
			*ret_cam = cam;
			return true;
		}
	return false;
}

Status read_dir(const std::string &dir, ImageTable *ret)
{
	std::error_code ec;
	fs::directory_iterator it(dir, ec);
	if (ec)
		return Status::error(ENOENT, "cannot read directory " + dir + ": " + ec.message());
	std::map<int, std::map<int, std::string>> found;
	int cams = 0;
	for (const fs::directory_entry &e : it) {
		int pose = 0, cam = 0;
		if (!parse_image_name(e.path().filename().string(), &pose, &cam))
			continue;
		if (cam > 63)
			return Status::error(EINVAL, e.path().string() + ": camera index above 63");
		if (found[pose].count(cam))
			return Status::error(EINVAL, "two images for pose " + std::to_string(pose) +
							     " camera " + std::to_string(cam) + " in " + dir);
		found[pose][cam] = e.path().string();
		cams = std::max(cams, cam + 1);
	}
	if (found.empty())
		return Status::error(EINVAL, dir + ": no pose<k>_cam<i> images");
	ImageTable table;
	for (const auto &pose : found) {
		std::vector<std::string> row(static_cast<size_t>(cams), std::string());
		for (const auto &cam : pose.second)
			row[size_t(cam.first)] = cam.second;
		table.push_back(row);
	}
	*ret = std::move(table);
	return Status();
}

} // namespace

int calibrate_main(int argc, char **argv)
{
	enum { OPT_PAIRS = 256, OPT_DIR, OPT_BOARD, OPT_SQUARE, OPT_CHARUCO, OPT_MARKER, OPT_DICT,
	       OPT_DETECTOR, OPT_ORIGIN, OPT_MIN_VIEWS, OPT_ID };
	static const option options[] = {
		{"pairs", required_argument, nullptr, OPT_PAIRS},
		{"dir", required_argument, nullptr, OPT_DIR},
		{"board", required_argument, nullptr, OPT_BOARD},
		{"square-mm", required_argument, nullptr, OPT_SQUARE},
		{"charuco", no_argument, nullptr, OPT_CHARUCO},
		{"marker-mm", required_argument, nullptr, OPT_MARKER},
		{"dict", required_argument, nullptr, OPT_DICT},
		{"detector", required_argument, nullptr, OPT_DETECTOR},
		{"origin", required_argument, nullptr, OPT_ORIGIN},
		{"min-views", required_argument, nullptr, OPT_MIN_VIEWS},
		{"id", required_argument, nullptr, OPT_ID},
		{"output", required_argument, nullptr, 'o'},
		{"help", no_argument, nullptr, 'h'},
		{nullptr, 0, nullptr, 0},
	};
	std::string pairs, dir, board_text, output, id;
	calib::BoardSpec board;
	calib::DetectParams detect;
	calib::CalibParams params;
	bool have_square = false;
	auto number = [](const char *s, double *ret) {
		char *end = nullptr;
		*ret = std::strtod(s, &end);
		return end != s && !*end;
	};
	optind = 0; // GNU getopt: 0 re-initialises (the verb may run more than once in a process)
	opterr = 0;
	for (int c; (c = getopt_long(argc, argv, "o:h", options, nullptr)) != -1;) {
		double v = 0;
		switch (c) {
		case OPT_PAIRS: pairs = optarg; break;
		case OPT_DIR: dir = optarg; break;
		case OPT_BOARD: board_text = optarg; break;
		case OPT_SQUARE:
			if (!number(optarg, &board.square_mm) || !(board.square_mm > 0))
				return bad_usage(std::string("--square-mm '") + optarg + "': want a size in mm > 0");
			have_square = true;
			break;
		case OPT_CHARUCO: board.type = calib::TargetType::Charuco; break;
		case OPT_MARKER:
			if (!number(optarg, &board.marker_mm) || !(board.marker_mm > 0))
				return bad_usage(std::string("--marker-mm '") + optarg + "': want a size in mm > 0");
			break;
		case OPT_DICT: {
			Status st = calib::parse_dictionary(optarg, &board.dictionary);
			if (!st.ok())
				return bad_usage(st.message());
			break;
		}
		case OPT_DETECTOR:
			if (!std::strcmp(optarg, "sb"))
				detect.detector = calib::ChessboardDetector::SectorBased;
			else if (!std::strcmp(optarg, "classic"))
				detect.detector = calib::ChessboardDetector::Classic;
			else
				return bad_usage(std::string("--detector '") + optarg + "': want sb or classic");
			break;
		case OPT_ORIGIN:
			if (!std::strcmp(optarg, "cam0"))
				params.origin_pose = -1;
			else if (!std::strncmp(optarg, "pose:", 5) && number(optarg + 5, &v) && v >= 0 &&
				 v == double(int(v)))
				params.origin_pose = int(v);
			else
				return bad_usage(std::string("--origin '") + optarg + "': want cam0 or pose:K");
			break;
		case OPT_MIN_VIEWS:
			if (!number(optarg, &v) || v < 3 || v != double(int(v)))
				return bad_usage(std::string("--min-views '") + optarg + "': want an integer >= 3");
			params.min_views_per_camera = int(v);
			break;
		case OPT_ID: id = optarg; break;
		case 'o': output = optarg; break;
		case 'h': usage(stdout); return 0;
		default:
			return bad_usage(std::string("unknown or incomplete option '") + argv[optind - 1] + "'");
		}
	}
	if (optind < argc)
		return bad_usage(std::string("unexpected argument '") + argv[optind] + "'");
	if (pairs.empty() == dir.empty())
		return bad_usage("give exactly one of --pairs LIST or --dir DIR");
	if (board_text.empty() || !have_square)
		return bad_usage("--board COLSxROWS and --square-mm S are required");
	if (output.empty())
		return bad_usage("-o OUT.yaml is required");
	Status st = calib::parse_board_size(board_text, &board.cols, &board.rows);
	if (!st.ok())
		return bad_usage(st.message());
	st = calib::validate_board(board);
	if (!st.ok())
		return bad_usage(st.message());

	ImageTable table;
	st = pairs.empty() ? read_dir(dir, &table) : read_pairs(pairs, &table);
	if (!st.ok())
		return failure(st.message());
	// The calibration never replaces an image or the pair list it was made from.
	std::vector<InputFile> inputs;
	if (!pairs.empty())
		inputs.push_back({pairs, "the pair list"});
	for (const std::vector<std::string> &pose : table)
		for (const std::string &image : pose)
			if (!image.empty())
				inputs.push_back({image, "a board image"});
	std::string why;
	if (!check_outputs(inputs, {{output, ".yaml"}}, &why))
		return bad_usage(why);
	const size_t poses = table.size(), cams = table[0].size();
	if (cams < 2)
		return failure("images of at least 2 cameras are needed (found camera 0 only)");

	// Detect the board in every image, in parallel; report in order afterwards.
	std::vector<std::vector<calib::BoardView>> views(poses, std::vector<calib::BoardView>(cams));
	std::vector<std::vector<cv::Size>> image_sizes(poses, std::vector<cv::Size>(cams));
	cv::parallel_for_(cv::Range(0, int(poses * cams)), [&](const cv::Range &r) {
		for (int k = r.start; k < r.end; k++) {
			const size_t p = size_t(k) / cams, c = size_t(k) % cams;
			if (table[p][c].empty()) {
				views[p][c].reason = "no image";
				continue;
			}
			// imread would wait forever on a FIFO and decode any size.
			if (!check_regular_file(table[p][c], kMaxBoardImageBytes).ok()) {
				views[p][c].reason = "not a regular file of at most 256 MB";
				continue;
			}
			const cv::Mat img = cv::imread(table[p][c], cv::IMREAD_GRAYSCALE);
			if (img.empty()) {
				views[p][c].reason = "cannot read the image";
				continue;
			}
			image_sizes[p][c] = img.size();
			views[p][c] = calib::detect_board(img, board, detect);
		}
	});
	std::vector<cv::Size> sizes(cams);
	for (size_t c = 0; c < cams; c++)
		for (size_t p = 0; p < poses; p++) {
			calib::BoardView &v = views[p][c];
			const cv::Size s = image_sizes[p][c];
			if (s.area() && !sizes[c].area())
				sizes[c] = s;
			if (v.found && s != sizes[c]) {
				v.found = false;
				v.reason = "image is " + std::to_string(s.width) + "x" +
					   std::to_string(s.height) + ", the camera's first image is " +
					   std::to_string(sizes[c].width) + "x" +
					   std::to_string(sizes[c].height);
			}
		}
	int skipped = 0, found = 0;
	for (size_t p = 0; p < poses; p++)
		for (size_t c = 0; c < cams; c++) {
			if (views[p][c].found) {
				found++;
			} else if (!table[p][c].empty()) {
				std::printf("skipped %s: %s\n", table[p][c].c_str(),
					    views[p][c].reason.c_str());
				skipped++;
			}
		}
	std::printf("%zu poses x %zu cameras: board found in %d images, %d skipped\n", poses, cams,
		    found, skipped);
	for (size_t c = 0; c < cams; c++)
		if (!sizes[c].area())
			return failure("camera " + std::to_string(c) + " has no readable image");

	Calibration cal;
	calib::RigReport report;
	st = calib::calibrate_rig(views, sizes, params, &cal, &report);
	if (!st.ok())
		return failure(st.message() + "; nothing written");
	cal.id = id;
	for (const std::string &d : report.dropped)
		std::printf("dropped %s\n", d.c_str());
	for (size_t c = 0; c < cams; c++) {
		const CameraModel &m = cal.cameras[c];
		std::printf("camera %zu: %d views, RMS %.3f px alone, %.3f px joint; fx %.2f fy %.2f "
			    "cx %.2f cy %.2f; k1 %.4f k2 %.4f p1 %.5f p2 %.5f k3 %.4f\n",
			    c, report.cameras[c].views, report.cameras[c].intrinsic_rms_px,
			    report.cameras[c].final_rms_px, m.K(0, 0), m.K(1, 1), m.K(0, 2), m.K(1, 2),
			    m.dist[0], m.dist[1], m.dist[2], m.dist[3], m.dist[4]);
	}
	for (const calib::PairReport &pr : report.pairs) {
		const cv::Vec3d ca = cal.cameras[size_t(pr.cam_a)].centre(),
				cb = cal.cameras[size_t(pr.cam_b)].centre();
		std::printf("pair %d-%d: %d shared views, stereo RMS %.3f px chained, %.3f px joint; "
			    "baseline %.2f mm\n",
			    pr.cam_a, pr.cam_b, pr.views, pr.chain_rms_px, pr.final_rms_px, cv::norm(cb - ca));
	}
	std::printf("joint refinement: %d iterations, RMS %.3f px over %d corners\n", report.iterations,
		    report.final_rms_px, report.observations);
	std::printf("world frame: %s\n", report.world_frame.c_str());
	if (cams == 2)
		std::printf("Stereo calibration RMS reprojection error: %.4f px\n",
			    report.pairs[0].final_rms_px);
	st = write_calibration(output, cal);
	if (!st.ok())
		return failure(st.message());
	std::printf("wrote %s\n", output.c_str());
	return 0;
}

} // namespace facescan::cli
