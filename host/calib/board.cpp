// The calibration target: its description, its geometry and its detection in an image.
#include "calib/calib.hpp"

#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cctype>
#include <cstdlib>

namespace facescan::calib {

Status validate_board(const BoardSpec &board)
{
	if (board.cols < 2 || board.rows < 2 || board.cols > 200 || board.rows > 200)
		return Status::error(EINVAL, "board " + std::to_string(board.cols) + "x" +
						     std::to_string(board.rows) +
						     ": need 2..200 inner corners each way");
	if (!(board.square_mm > 0))
		return Status::error(EINVAL, "board square size must be > 0 mm");
	if (board.type == TargetType::Chessboard) {
		// A board with cols + rows even looks the same after a half turn: two cameras could
		// number its corners from opposite ends and no image tells which is right.
		if ((board.cols + board.rows) % 2 == 0)
			return Status::error(EINVAL, "chessboard " + std::to_string(board.cols) + "x" +
							     std::to_string(board.rows) +
							     " is symmetric under a half turn: use one odd and one "
							     "even inner-corner count (e.g. 9x6)");
		return Status();
	}
	if (!(board.marker_mm > 0) || board.marker_mm >= board.square_mm)
		return Status::error(EINVAL, "ChArUco marker size must be > 0 and < the square size");
	if (board.dictionary < cv::aruco::DICT_4X4_50 ||
	    board.dictionary > cv::aruco::DICT_APRILTAG_36h11)
		return Status::error(EINVAL, "unknown ArUco dictionary " +
						     std::to_string(board.dictionary));
	const int markers = ((board.cols + 1) * (board.rows + 1)) / 2;
	const int capacity = cv::aruco::getPredefinedDictionary(board.dictionary)->bytesList.rows;
	if (markers > capacity)
		return Status::error(EINVAL, "ChArUco board needs " + std::to_string(markers) +
						     " markers, the dictionary has " +
						     std::to_string(capacity));
	return Status();
}

Status parse_board_size(const std::string &text, int *ret_cols, int *ret_rows)
{
	const char *s = text.c_str();
	char *end = nullptr;
	long cols = std::strtol(s, &end, 10);
	if (end == s || (*end != 'x' && *end != 'X'))
		return Status::error(EINVAL, "board size '" + text + "': want COLSxROWS, e.g. 9x6");
	const char *r = end + 1;
	long rows = std::strtol(r, &end, 10);
	if (end == r || *end || cols < 2 || rows < 2 || cols > 200 || rows > 200)
		return Status::error(EINVAL, "board size '" + text +
						     "': want COLSxROWS inner corners, 2..200 each");
	*ret_cols = int(cols);
	*ret_rows = int(rows);
	return Status();
}

Status parse_dictionary(const std::string &text, int *ret_dictionary)
{
	static const struct {
		const char *name;
		int value;
	} names[] = {
		{"4X4_50", cv::aruco::DICT_4X4_50},	{"4X4_100", cv::aruco::DICT_4X4_100},
		{"4X4_250", cv::aruco::DICT_4X4_250},	{"4X4_1000", cv::aruco::DICT_4X4_1000},
		{"5X5_50", cv::aruco::DICT_5X5_50},	{"5X5_100", cv::aruco::DICT_5X5_100},
		{"5X5_250", cv::aruco::DICT_5X5_250},	{"5X5_1000", cv::aruco::DICT_5X5_1000},
		{"6X6_50", cv::aruco::DICT_6X6_50},	{"6X6_100", cv::aruco::DICT_6X6_100},
		{"6X6_250", cv::aruco::DICT_6X6_250},	{"6X6_1000", cv::aruco::DICT_6X6_1000},
		{"7X7_50", cv::aruco::DICT_7X7_50},	{"7X7_100", cv::aruco::DICT_7X7_100},
		{"7X7_250", cv::aruco::DICT_7X7_250},	{"7X7_1000", cv::aruco::DICT_7X7_1000},
		{"ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL},
	};
	std::string key = text;
	std::transform(key.begin(), key.end(), key.begin(),
		       [](unsigned char c) { return char(std::toupper(c)); });
	if (key.rfind("DICT_", 0) == 0)
		key = key.substr(5);
	for (const auto &n : names)
		if (key == n.name) {
			*ret_dictionary = n.value;
			return Status();
		}
	return Status::error(EINVAL, "unknown ArUco dictionary '" + text +
					     "' (e.g. DICT_5X5_1000, DICT_4X4_50, DICT_6X6_250)");
}

std::vector<cv::Point3f> board_object_points(const BoardSpec &board)
{
	std::vector<cv::Point3f> points;
	points.reserve(size_t(board.cols) * size_t(board.rows));
	for (int r = 0; r < board.rows; r++)
		for (int c = 0; c < board.cols; c++)
			points.emplace_back(float(c * board.square_mm), float(r * board.square_mm), 0.f);
	return points;
}

namespace {

float mean_around(const cv::Mat &gray, cv::Point2f at)
{
	cv::Mat patch;
	cv::getRectSubPix(gray, cv::Size(3, 3), at, patch, CV_32F);
	return float(cv::mean(patch)[0]);
}

// Puts detected chessboard corners in the board's canonical order. The detectors return the
// grid in one of four orders (the board's two flips and half turn look alike to them); the
// front side fixes the handedness and the colour of the corner squares fixes the half turn.
void canonical_order(const cv::Mat &gray, int cols, int rows, std::vector<cv::Point2f> *corners)
{
	std::vector<cv::Point2f> &p = *corners;
	const cv::Point2f ex = p[1] - p[0], ey = p[size_t(cols)] - p[0];
	// Board x right, y down, seen from its printed side: image cross product is positive.
	if (ex.x * ey.y - ex.y * ey.x < 0)
		for (int r = 0; r < rows; r++)
			std::reverse(p.begin() + r * cols, p.begin() + (r + 1) * cols);
	const size_t n = p.size(), c = size_t(cols);
	const cv::Point2f first = (p[0] + p[1] + p[c] + p[c + 1]) * 0.25f;
	const cv::Point2f last = (p[n - 1] + p[n - 2] + p[n - 1 - c] + p[n - 2 - c]) * 0.25f;
	// The square diagonally inside corner 0 is black; the one inside the last corner is white.
	if (mean_around(gray, first) > mean_around(gray, last))
		std::reverse(p.begin(), p.end());
}

BoardView detect_chessboard(const cv::Mat &gray, const BoardSpec &board, const DetectParams &params)
{
	BoardView view;
	const cv::Size pattern(board.cols, board.rows);
	std::vector<cv::Point2f> corners;
	bool found;
	if (params.detector == ChessboardDetector::SectorBased && gray.cols > params.max_search_width) {
		// Find the grid on a smaller copy (the detector's cost grows with the pixel count),
		// then refine every corner on the full image.
		const double f = double(params.max_search_width) / gray.cols;
		cv::Mat small;
		cv::resize(gray, small, cv::Size(), f, f, cv::INTER_AREA);
		found = cv::findChessboardCornersSB(small, pattern, corners, cv::CALIB_CB_ACCURACY);
		if (found) {
			for (cv::Point2f &p : corners)
				p = (p + cv::Point2f(0.5f, 0.5f)) * float(1 / f) - cv::Point2f(0.5f, 0.5f);
			// Window: a third of the closest corner spacing, 2..7 pixels each side.
			float spacing = 1e9f;
			for (int r = 0; r < board.rows; r++)
				for (int c = 0; c + 1 < board.cols; c++)
					spacing = std::min(spacing, float(cv::norm(corners[size_t(r * board.cols + c + 1)] -
										    corners[size_t(r * board.cols + c)])));
			for (int r = 0; r + 1 < board.rows; r++)
				for (int c = 0; c < board.cols; c++)
					spacing = std::min(spacing, float(cv::norm(corners[size_t((r + 1) * board.cols + c)] -
										    corners[size_t(r * board.cols + c)])));
			const int win = std::clamp(int(spacing / 3), 2, 7);
			cv::cornerSubPix(gray, corners, cv::Size(win, win), cv::Size(-1, -1),
					 cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 100, 1e-4));
		}
	} else if (params.detector == ChessboardDetector::SectorBased) {
		found = cv::findChessboardCornersSB(gray, pattern, corners, cv::CALIB_CB_ACCURACY);
	} else {
		found = cv::findChessboardCorners(gray, pattern, corners,
						  cv::CALIB_CB_ADAPTIVE_THRESH |
							  cv::CALIB_CB_NORMALIZE_IMAGE);
		if (found)
			cv::cornerSubPix(gray, corners, cv::Size(5, 5), cv::Size(-1, -1),
					 cv::TermCriteria(cv::TermCriteria::EPS |
								  cv::TermCriteria::COUNT,
							  50, 0.001));
	}
	if (!found || corners.size() != size_t(board.cols) * size_t(board.rows)) {
		view.reason = "chessboard " + std::to_string(board.cols) + "x" +
			      std::to_string(board.rows) + " not found";
		return view;
	}
	canonical_order(gray, board.cols, board.rows, &corners);
	view.found = true;
	view.image_points = std::move(corners);
	view.object_points = board_object_points(board);
	view.ids.resize(view.image_points.size());
	for (size_t i = 0; i < view.ids.size(); i++)
		view.ids[i] = int(i);
	return view;
}

BoardView detect_charuco(const cv::Mat &gray, const BoardSpec &board, const DetectParams &params)
{
	BoardView view;
	cv::Ptr<cv::aruco::Dictionary> dict = cv::aruco::getPredefinedDictionary(board.dictionary);
	cv::Ptr<cv::aruco::CharucoBoard> charuco = cv::aruco::CharucoBoard::create(
		board.cols + 1, board.rows + 1, float(board.square_mm), float(board.marker_mm), dict);
	std::vector<std::vector<cv::Point2f>> marker_corners;
	std::vector<int> marker_ids;
	cv::Ptr<cv::aruco::DetectorParameters> dp = cv::aruco::DetectorParameters::create();
	cv::aruco::detectMarkers(gray, dict, marker_corners, marker_ids, dp);
	if (marker_ids.empty()) {
		view.reason = "no ArUco marker of the board's dictionary found";
		return view;
	}
	std::vector<cv::Point2f> corners;
	std::vector<int> ids;
	cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, gray, charuco, corners,
					     ids);
	if (int(ids.size()) < params.min_charuco_corners) {
		view.reason = "only " + std::to_string(ids.size()) + " ChArUco corners found (need " +
			      std::to_string(params.min_charuco_corners) + ")";
		return view;
	}
	// Refine the corners the way the chessboard detector does.
	cv::cornerSubPix(gray, corners, cv::Size(5, 5), cv::Size(-1, -1),
			 cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 50,
					  0.001));
	std::vector<size_t> order(ids.size());
	for (size_t i = 0; i < order.size(); i++)
		order[i] = i;
	std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return ids[a] < ids[b]; });
	// OpenCV's ChArUco corners are measured from the board's outer corner; ours from corner 0.
	const cv::Point3f origin = charuco->chessboardCorners[0];
	for (size_t i : order) {
		view.ids.push_back(ids[i]);
		view.image_points.push_back(corners[i]);
		view.object_points.push_back(charuco->chessboardCorners[size_t(ids[i])] - origin);
	}
	view.found = true;
	return view;
}

} // namespace

BoardView detect_board(const cv::Mat &image, const BoardSpec &board, const DetectParams &params)
{
	BoardView view;
	Status st = validate_board(board);
	if (!st.ok()) {
		view.reason = st.message();
		return view;
	}
	if (image.empty() || image.depth() != CV_8U ||
	    (image.channels() != 1 && image.channels() != 3)) {
		view.reason = "not an 8-bit gray or colour image";
		return view;
	}
	cv::Mat gray;
	if (image.channels() == 3)
		cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
	else
		gray = image;
	try {
		return board.type == TargetType::Chessboard ? detect_chessboard(gray, board, params)
							    : detect_charuco(gray, board, params);
	} catch (const cv::Exception &e) {
		view = BoardView();
		view.reason = std::string("OpenCV: ") + e.what();
		return view;
	}
}

} // namespace facescan::calib
