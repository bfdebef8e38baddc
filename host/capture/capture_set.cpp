// Capture-set reader and writer. Format: docs/capture-format.md.
#include "capture/capture_set.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace facescan {

namespace {

std::string errno_text(int e)
{
	return std::strerror(e);
}

std::string dir_of(const std::string &path)
{
	size_t slash = path.find_last_of('/');
	return slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash));
}

bool exists(const std::string &path)
{
	struct stat st;
	return stat(path.c_str(), &st) == 0;
}

// A number for a message: 1e+308, 0.04, 1600.
std::string num(double v)
{
	char buf[32];
	std::snprintf(buf, sizeof buf, "%.6g", v);
	return buf;
}

std::string cam_key(int i, const char *field)
{
	return "cam" + std::to_string(i) + "_" + field;
}

// The deepest bracket nesting of a YAML/JSON text, over-estimated: quoted strings are skipped
// (with backslash escapes), and the result is the larger of the count with and without
// '#' comments, so no reading of the text a parser could take nests deeper than this. OpenCV's
// FileStorage and a JSON dump recurse once per level: ~40,000 '[' overflow the stack.
int max_nesting(const std::string &text, bool yaml)
{
	int worst = 0;
	for (int comments = 0; comments < (yaml ? 2 : 1); comments++) {
		int depth = 0;
		char quote = 0;
		bool comment = false;
		for (size_t i = 0; i < text.size(); i++) {
			const char c = text[i];
			if (comment) {
				if (c == '\n')
					comment = false;
				continue;
			}
			if (quote) {
				if (c == '\\' && quote == '"')
					i++;
				else if (c == quote)
					quote = 0;
				continue;
			}
			if (c == '"' || (yaml && c == '\''))
				quote = c;
			else if (comments && c == '#' && (i == 0 || std::isspace(static_cast<unsigned char>(text[i - 1]))))
				comment = true;
			else if (c == '[' || c == '{')
				worst = std::max(worst, ++depth);
			else if ((c == ']' || c == '}') && depth > 0)
				depth--;
		}
	}
	return worst;
}

// OpenCV 4.6's YAML parser never returns on some texts whose top-level map is indented and
// then dedented: "%YAML:1.0\n---\n u: m\n- 1\n- 1\n", "--- u: m" (content on the marker line)
// followed by two "- 1" lines, or a second document ("---" or "...") after an indented map,
// "%YAML:1.0\n---\n  u: m\n---\n- 1\n" (all found by tests/host/fuzz_calibration, minimised by
// hand). A calibration.yaml as OpenCV (C++ or Python) writes it has one layout, checked before
// the parser runs: "%" directives, one "---" line alone, then the fields, the first at column
// 0; no second document marker. Empty if the text has that layout, else why not.
std::string yaml_layout_problem(const std::string &text)
{
	bool content = false;
	int markers = 0;
	for (size_t i = 0; i <= text.size();) {
		size_t end = text.find_first_of("\r\n", i);
		if (end == std::string::npos)
			end = text.size();
		const std::string line = text.substr(i, end - i);
		i = end + 1;
		const size_t k = line.find_first_not_of(" \t");
		const bool blank = k == std::string::npos || line[k] == '#';
		if (line.compare(0, 3, "---") == 0 || line.compare(0, 3, "...") == 0) {
			if (line[0] == '.' || content || ++markers > 1)
				return "more than one YAML document (a '---' or '...' line after the first "
				       "content)";
			const size_t r = line.find_first_not_of(" \t", 3);
			if (r != std::string::npos && line[r] != '#')
				return "content on the '---' line";
			continue;
		}
		if (!content && !line.empty() && line[0] == '%')
			continue; // a directive
		if (blank || content)
			continue;
		if (k != 0)
			return "the first field is indented (the top-level map must start at column 0)";
		content = true;
	}
	return {};
}

// What a calibration or metadata file may hold: ours are a few kB.
constexpr size_t kMaxTextFileBytes = 1 << 20;
// Our files nest 2 deep (a matrix's data in a map; the trigger report's arrays in capture.json).
constexpr int kMaxNesting = 32;
// Image sizes a reader accepts: a 1600x1200 camera is 1.9 MP; the largest machine-vision
// sensors are ~25 MP. Bounding it bounds what decoding a frame may allocate.
constexpr int kMaxImageSide = 10000;
constexpr long long kMaxImagePixels = 40LL * 1000 * 1000;

// OpenCV 4.6's `node >> mat` allocates the rows x cols (or "sizes") a node declares before it
// counts the node's data: a dozen lines declaring 1000000000 x 1000000000 asked for 8 EB
// (std::bad_alloc; an abort under ASan; found by tests/host/fuzz_calibration), 20000 x 20000
// for 3.2 GB. So a matrix node is checked first: only rows, cols, dt and data; at most
// kMaxMatrixSide per side, one channel; exactly rows x cols numbers. Empty if it passes, else why.
constexpr int kMaxMatrixSide = 16;

std::string small_matrix_problem(const cv::FileNode &node)
{
	if (!node.isMap())
		return "is not a matrix";
	for (const std::string &k : node.keys())
		if (k != "rows" && k != "cols" && k != "dt" && k != "data")
			return "is not a matrix (unexpected key '" + k + "')";
	const cv::FileNode rows = node["rows"], cols = node["cols"], dt = node["dt"], data = node["data"];
	if (!rows.isInt() || !cols.isInt() || !dt.isString() || !data.isSeq())
		return "is not a matrix (needs integer rows and cols, a dt and a data sequence)";
	const int r = int(rows), c = int(cols);
	if (r < 1 || r > kMaxMatrixSide || c < 1 || c > kMaxMatrixSide)
		return "declares " + std::to_string(r) + "x" + std::to_string(c) + ", not a matrix of 1.." +
		       std::to_string(kMaxMatrixSide) + " rows and columns";
	const std::string type = std::string(dt);
	if (type.size() != 1 || std::string("ucwsifd").find(type[0]) == std::string::npos)
		return "has dt '" + type + "', not one channel of a number type (u c w s i f d)";
	if (data.size() != size_t(r) * size_t(c))
		return "declares " + std::to_string(r) + "x" + std::to_string(c) + " but holds " +
		       std::to_string(data.size()) + " values";
	for (size_t k = 0; k < data.size(); k++)
		if (!data[int(k)].isInt() && !data[int(k)].isReal())
			return "holds a value that is not a number";
	return {};
}

// Reads a real matrix node of exactly rows x cols (either orientation for vectors).
Status read_matrix(const cv::FileStorage &fs, const std::string &file, const std::string &key,
		   int rows, int cols, cv::Mat *ret)
{
	cv::FileNode node = fs[key];
	if (node.empty())
		return Status::error(EINVAL, file + ": missing field '" + key + "'");
	const std::string problem = small_matrix_problem(node);
	if (!problem.empty())
		return Status::error(EINVAL, file + ": field '" + key + "' " + problem);
	cv::Mat m;
	try {
		node >> m;
	} catch (const cv::Exception &) {
		m.release();
	}
	if (m.empty())
		return Status::error(EINVAL, file + ": field '" + key + "' is not a matrix");
	bool vector_ok = (rows == 1 || cols == 1) && int(m.total()) == rows * cols &&
			 (m.rows == 1 || m.cols == 1);
	if (!(m.rows == rows && m.cols == cols) && !vector_ok)
		return Status::error(EINVAL, file + ": field '" + key + "' must be " +
						     std::to_string(rows) + "x" + std::to_string(cols) +
						     ", got " + std::to_string(m.rows) + "x" +
						     std::to_string(m.cols));
	m.convertTo(m, CV_64F);
	m = m.reshape(1, rows);
	for (int k = 0; k < int(m.total()); k++)
		if (!std::isfinite(m.at<double>(k)))
			return Status::error(EINVAL, file + ": field '" + key + "' has a non-finite value");
	*ret = m;
	return {};
}

Status check_calibration(const std::string &file, const Calibration &c)
{
	for (size_t i = 0; i < c.cameras.size(); i++) {
		const CameraModel &cam = c.cameras[i];
		const int k = int(i);
		std::string who = file + ": camera " + std::to_string(i);
		if (cam.size.width <= 0 || cam.size.height <= 0 || cam.size.width > kMaxImageSide ||
		    cam.size.height > kMaxImageSide ||
		    (long long)cam.size.width * cam.size.height > kMaxImagePixels)
			return Status::error(EINVAL, who + ": field '" + cam_key(k, "size") + "' is " +
							     std::to_string(cam.size.width) + "x" +
							     std::to_string(cam.size.height) +
							     ", not a plausible image size (each side 1.." +
							     std::to_string(kMaxImageSide) + ", at most " +
							     std::to_string(kMaxImagePixels / 1000000) + " MP)");
		if (cam.K(0, 0) <= 0 || cam.K(1, 1) <= 0 || cam.K(2, 2) != 1.0 || cam.K(1, 0) != 0 ||
		    cam.K(2, 0) != 0 || cam.K(2, 1) != 0)
			return Status::error(EINVAL, who + ": field '" + cam_key(k, "K") +
							     "' is not a camera matrix");
		// Focal lengths from a 170-degree fisheye (0.04 widths) to a 0.3-degree telephoto (200
		// widths): anything outside is a typo or a unit error, and silently degrades the scan.
		const double w = cam.size.width, h = cam.size.height;
		for (double f : {cam.K(0, 0), cam.K(1, 1)})
			if (f < 0.04 * w || f > 200 * w)
				return Status::error(EINVAL, who + ": field '" + cam_key(k, "K") +
								     "': focal length " + num(f) +
								     " px is implausible for a " +
								     std::to_string(cam.size.width) +
								     " px wide image (0.04..200 widths)");
		if (std::abs(cam.K(0, 1)) > cam.K(0, 0))
			return Status::error(EINVAL, who + ": field '" + cam_key(k, "K") + "': skew " +
							     num(cam.K(0, 1)) + " exceeds the focal length");
		if (cam.K(0, 2) < -0.5 * w || cam.K(0, 2) > 1.5 * w || cam.K(1, 2) < -0.5 * h ||
		    cam.K(1, 2) > 1.5 * h)
			return Status::error(EINVAL, who + ": field '" + cam_key(k, "K") +
							     "': principal point (" + num(cam.K(0, 2)) +
							     ", " + num(cam.K(1, 2)) +
							     ") lies far outside the image");
		for (int d = 0; d < 5; d++)
			if (!std::isfinite(cam.dist[d]) || std::abs(cam.dist[d]) > 1000)
				return Status::error(EINVAL, who + ": field '" + cam_key(k, "dist") +
								     "': coefficient " + num(cam.dist[d]) +
								     " is implausible (|k| <= 1000)");
		cv::Matx33d should_be_eye = cam.R * cam.R.t();
		if (cv::norm(should_be_eye - cv::Matx33d::eye()) > 1e-6 || cv::determinant(cam.R) < 0)
			return Status::error(EINVAL, who + ": field '" + cam_key(k, "R") +
							     "' is not a rotation");
		// A booth is about a metre across; 10 m is a unit error (m for mm) or garbage.
		const double t_max = std::max({std::abs(cam.T[0]), std::abs(cam.T[1]), std::abs(cam.T[2])});
		if (!(t_max <= 10000))
			return Status::error(EINVAL, who + ": field '" + cam_key(k, "T") + "' has " + num(t_max) +
							     " mm, the camera is more than 10 m from the world origin");
	}
	return {};
}

// cam{i}_size as C++ writes a cv::Size ([w, h]) or as Python's cv2.FileStorage does (a 1x2 or
// 2x1 !!opencv-matrix of int or double). The values must be whole numbers.
Status read_size(const cv::FileStorage &fs, const std::string &file, const std::string &key,
		 cv::Size *ret)
{
	cv::FileNode node = fs[key];
	const std::string want = file + ": field '" + key +
				 "' must be [width, height] or a 1x2 matrix of whole numbers";
	double v[2];
	if (node.isSeq()) {
		if (node.size() != 2)
			return Status::error(EINVAL, want);
		for (int k = 0; k < 2; k++) {
			if (!node[k].isInt() && !node[k].isReal())
				return Status::error(EINVAL, want);
			v[k] = node[k].isInt() ? double(int(node[k])) : double(node[k]);
		}
	} else if (node.isMap()) {
		if (!small_matrix_problem(node).empty())
			return Status::error(EINVAL, want);
		cv::Mat m;
		try {
			node >> m;
		} catch (const cv::Exception &) {
			m.release();
		}
		if (m.empty() || m.total() != 2 || !(m.rows == 1 || m.cols == 1) || m.channels() != 1)
			return Status::error(EINVAL, want);
		m.convertTo(m, CV_64F);
		v[0] = m.at<double>(0);
		v[1] = m.at<double>(1);
	} else {
		return Status::error(EINVAL, want);
	}
	for (double x : v)
		if (!std::isfinite(x) || x != std::floor(x))
			return Status::error(EINVAL, want + ", got a fractional or non-finite value");
	for (double x : v)
		if (x < 1 || x > kMaxImageSide)
			return Status::error(EINVAL, file + ": field '" + key + "': " + num(x) +
							     " is not a plausible image side (1.." +
							     std::to_string(kMaxImageSide) + " px)");
	*ret = cv::Size(int(v[0]), int(v[1]));
	return {};
}

// What read_regular_file and check_regular_file accept: a regular file of at most max_bytes.
Status regular_and_small(const std::string &path, const struct stat &st, size_t max_bytes)
{
	if (!S_ISREG(st.st_mode))
		return Status::error(EINVAL, path + ": not a regular file");
	if (static_cast<unsigned long long>(st.st_size) > max_bytes)
		return Status::error(EFBIG, path + ": " + std::to_string(st.st_size) + " bytes, more than the " +
						    std::to_string(max_bytes) + " this file may have");
	return {};
}

} // namespace

Status read_regular_file(const std::string &path, size_t max_bytes, std::string *ret)
{
	int fd = open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
	if (fd < 0) {
		int e = errno;
		if (e == ENOENT)
			return Status::error(ENOENT, path + ": missing");
		return Status::error(e, path + ": cannot open: " + errno_text(e));
	}
	struct stat st;
	if (fstat(fd, &st) < 0) {
		int e = errno;
		close(fd);
		return Status::error(e, path + ": cannot stat: " + errno_text(e));
	}
	if (Status verdict = regular_and_small(path, st, max_bytes); !verdict.ok()) {
		close(fd);
		return verdict;
	}
	std::string text(size_t(st.st_size), '\0');
	size_t got = 0;
	while (got < text.size()) {
		ssize_t n = read(fd, &text[got], text.size() - got);
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0) {
			int e = errno;
			close(fd);
			return Status::error(e, path + ": read failed: " + errno_text(e));
		}
		if (n == 0)
			break; // shrank while we read: take what is there, the parser judges it
		got += size_t(n);
	}
	close(fd);
	text.resize(got);
	*ret = std::move(text);
	return {};
}

Status check_regular_file(const std::string &path, size_t max_bytes)
{
	struct stat st;
	if (stat(path.c_str(), &st) != 0) {
		int e = errno;
		if (e == ENOENT)
			return Status::error(ENOENT, path + ": missing");
		return Status::error(e, path + ": cannot open: " + errno_text(e));
	}
	return regular_and_small(path, st, max_bytes);
}

Status write_file_atomic(const std::string &path, const void *data, size_t size)
{
	std::string dir = dir_of(path);
	std::string tmpl = path + ".tmp.XXXXXX";
	std::vector<char> name(tmpl.begin(), tmpl.end());
	name.push_back('\0');
	int fd = mkostemp(name.data(), O_CLOEXEC);
	if (fd < 0)
		return Status::error(errno, path + ": cannot create temporary file: " + errno_text(errno));
	int err = 0;
	const char *p = static_cast<const char *>(data);
	size_t left = size;
	while (left > 0 && !err) {
		ssize_t n = write(fd, p, left);
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0)
			err = errno;
		else
			p += n, left -= size_t(n);
	}
	if (!err && fsync(fd) < 0)
		err = errno;
	if (!err && fchmod(fd, 0644) < 0)
		err = errno;
	if (close(fd) < 0 && !err)
		err = errno;
	if (!err && rename(name.data(), path.c_str()) < 0)
		err = errno;
	if (err) {
		unlink(name.data());
		return Status::error(err, path + ": write failed: " + errno_text(err));
	}
	// The rename is durable only once the directory entry is on disk.
	int dfd = open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (dfd >= 0) {
		fsync(dfd);
		close(dfd);
	}
	return {};
}

Status write_image_atomic(const std::string &path, const cv::Mat &image)
{
	size_t dot = path.find_last_of('.');
	if (dot == std::string::npos)
		return Status::error(EINVAL, path + ": no image extension");
	std::vector<uchar> bytes;
	bool ok = false;
	try {
		ok = cv::imencode(path.substr(dot), image, bytes);
	} catch (const cv::Exception &e) {
		return Status::error(EINVAL, path + ": cannot encode image: " + e.err);
	}
	if (!ok)
		return Status::error(EINVAL, path + ": cannot encode image");
	return write_file_atomic(path, bytes.data(), bytes.size());
}

Status read_calibration(const std::string &path, Calibration *ret_calibration)
{
	std::string text;
	Status rs = read_regular_file(path, kMaxTextFileBytes, &text);
	if (!rs.ok())
		return rs;
	return parse_calibration(text, path, ret_calibration);
}

Status parse_calibration(const std::string &text, const std::string &path,
			 Calibration *ret_calibration)
{
	if (text.size() > kMaxTextFileBytes)
		return Status::error(EFBIG, path + ": " + std::to_string(text.size()) +
						    " bytes, more than the " +
						    std::to_string(kMaxTextFileBytes) +
						    " this file may have");
	if (max_nesting(text, true) > kMaxNesting)
		return Status::error(EINVAL, path + ": nested more than " + std::to_string(kMaxNesting) +
						     " levels deep; not a calibration file");
	const std::string layout = yaml_layout_problem(text);
	if (!layout.empty())
		return Status::error(EINVAL, path + ": " + layout + "; not a calibration file");
	cv::FileStorage fs;
	try {
		// An empty text would make OpenCV take the string as a file name.
		fs.open(text.empty() ? std::string("%YAML:1.0\n") : text,
			cv::FileStorage::READ | cv::FileStorage::MEMORY | cv::FileStorage::FORMAT_YAML);
	} catch (const std::exception &) {
		// Not only cv::Exception: OpenCV 4.6's YAML parser throws std::length_error for the
		// 16 bytes "%YAML:1.\n s:1\n :" (found by tests/host/fuzz_calibration).
		return Status::error(EINVAL, path + ": not a readable OpenCV YAML file");
	}
	if (!fs.isOpened())
		return Status::error(EINVAL, path + ": not a readable OpenCV YAML file");
	// OpenCV's FileNode accessors throw cv::Exception where a node is not of the kind they
	// assert (fs["camera_count"] on a document whose root is a sequence, "- 1"): uncaught, that
	// aborted whatever read the file (found by tests/host/fuzz_calibration). Refused here, and
	// anything else OpenCV throws while the fields are read is -EINVAL too.
	const cv::FileNode root = fs.root();
	if (!root.empty() && !root.isMap())
		return Status::error(EINVAL, path + ": the top level is not a map of fields");
	auto read_fields = [&](Calibration *calib) -> Status {
		cv::FileNode count = fs["camera_count"];
		if (count.empty() || !count.isInt())
			return Status::error(EINVAL, path + ": missing or non-integer field 'camera_count'");
		int n = int(count);
		if (n < 2 || n > 16)
			return Status::error(EINVAL, path + ": field 'camera_count' must be 2..16, got " +
							     std::to_string(n));
		cv::FileNode units = fs["units"];
		if (units.empty() || !units.isString() || std::string(units) != "mm")
			return Status::error(EINVAL, path + ": field 'units' must be \"mm\"");
		if (fs["id"].isString())
			calib->id = std::string(fs["id"]);
		for (int i = 0; i < n; i++) {
			CameraModel cam;
			cv::Mat m;
			Status st = read_matrix(fs, path, cam_key(i, "K"), 3, 3, &m);
			if (!st.ok())
				return st;
			cam.K = cv::Matx33d(m);
			if (!(st = read_matrix(fs, path, cam_key(i, "dist"), 1, 5, &m)).ok())
				return st;
			cam.dist = cv::Vec<double, 5>(m.ptr<double>());
			if (!(st = read_matrix(fs, path, cam_key(i, "R"), 3, 3, &m)).ok())
				return st;
			cam.R = cv::Matx33d(m);
			if (!(st = read_matrix(fs, path, cam_key(i, "T"), 3, 1, &m)).ok())
				return st;
			cam.T = cv::Vec3d(m.ptr<double>());
			if (!(st = read_size(fs, path, cam_key(i, "size"), &cam.size)).ok())
				return st;
			calib->cameras.push_back(cam);
		}
		return {};
	};
	Calibration calib;
	try {
		Status fields = read_fields(&calib);
		if (!fields.ok())
			return fields;
	} catch (const std::exception &e) {
		return Status::error(EINVAL, path + ": not a readable calibration (OpenCV: " + e.what() + ")");
	}
	Status st = check_calibration(path, calib);
	if (!st.ok())
		return st;
	*ret_calibration = std::move(calib);
	return {};
}

Status write_calibration(const std::string &path, const Calibration &c)
{
	Status st = check_calibration(path, c);
	if (!st.ok())
		return st;
	std::string text;
	try {
		cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
		fs << "camera_count" << int(c.cameras.size());
		fs << "units" << c.units;
		if (!c.id.empty())
			fs << "id" << c.id;
		for (size_t i = 0; i < c.cameras.size(); i++) {
			const CameraModel &cam = c.cameras[i];
			int k = int(i);
			fs << cam_key(k, "K") << cv::Mat(cam.K);
			fs << cam_key(k, "dist") << cv::Mat(cam.dist).reshape(1, 1);
			fs << cam_key(k, "R") << cv::Mat(cam.R);
			fs << cam_key(k, "T") << cv::Mat(cam.T);
			fs << cam_key(k, "size") << "[" << cam.size.width << cam.size.height << "]";
		}
		text = fs.releaseAndGetString();
	} catch (const cv::Exception &e) {
		return Status::error(EINVAL, path + ": cannot serialise calibration: " + e.err);
	}
	return write_file_atomic(path, text.data(), text.size());
}

Status parse_capture_meta(const std::string &meta_text, const std::string &meta_path,
			  size_t n, CaptureMeta *ret_meta)
{
	if (meta_text.size() > kMaxTextFileBytes)
		return Status::error(EFBIG, meta_path + ": " + std::to_string(meta_text.size()) +
						    " bytes, more than the " +
						    std::to_string(kMaxTextFileBytes) +
						    " this file may have");
	CaptureMeta meta;
	// nlohmann parses any depth but dumps (trigger_report) recursively.
	if (max_nesting(meta_text, false) > kMaxNesting)
		return Status::error(EINVAL, meta_path + ": nested more than " +
						     std::to_string(kMaxNesting) + " levels deep");
	nlohmann::json j = nlohmann::json::parse(meta_text, nullptr, false);
	if (j.is_discarded() || !j.is_object())
		return Status::error(EINVAL, meta_path + ": not a JSON object");
	for (const char *key : {"scan_id", "pattern"})
		if (!j.contains(key) || !j[key].is_string() || j[key].get<std::string>().empty())
			return Status::error(EINVAL, meta_path + ": missing or invalid field '" +
							     key + "'");
	meta.scan_id = j["scan_id"].get<std::string>();
	meta.pattern_id = j["pattern"].get<std::string>();
	for (auto [key, out] : {std::pair{"timestamps_ns", &meta.timestamps_ns},
				std::pair{"exposure_us", &meta.exposure_us}}) {
		if (!j.contains(key))
			continue;
		const auto &a = j[key];
		if (!a.is_array() || a.size() != n)
			return Status::error(EINVAL, meta_path + ": field '" + key +
							     "' must be an array of one number per camera");
		for (const auto &v : a) {
			if (!v.is_number())
				return Status::error(EINVAL, meta_path + ": field '" + key +
								     "' must hold numbers");
			out->push_back(v.get<double>());
		}
	}
	if (j.contains("trigger_report"))
		meta.trigger_report_json = j["trigger_report"].dump();
	*ret_meta = std::move(meta);
	return {};
}

// Reads a PNG frame, checking the size its header declares against the calibration before
// anything is decoded: a 1 MB file may declare 20000x20000 pixels (1.2 GB decoded).
static Status read_frame(const std::string &path, const cv::Size &size, cv::Mat *ret)
{
	// A PNG is never much larger than its raw pixels (16-bit RGBA, stored blocks).
	const size_t max_bytes = size_t(size.width) * size_t(size.height) * 8 + (1 << 20);
	std::string bytes;
	Status st = read_regular_file(path, max_bytes, &bytes);
	if (!st.ok())
		return st;
	static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
	const unsigned char *b = reinterpret_cast<const unsigned char *>(bytes.data());
	if (bytes.size() < 33 || std::memcmp(b, kSignature, 8) != 0 || std::memcmp(b + 12, "IHDR", 4) != 0)
		return Status::error(EIO, path + ": cannot decode image (not a PNG file)");
	auto be32 = [](const unsigned char *p) {
		return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | uint32_t(p[3]);
	};
	const uint32_t w = be32(b + 16), h = be32(b + 20);
	if (w != uint32_t(size.width) || h != uint32_t(size.height))
		return Status::error(EINVAL, path + ": size " + std::to_string(w) + "x" + std::to_string(h) +
						     " does not match the calibration's " +
						     std::to_string(size.width) + "x" +
						     std::to_string(size.height));
	cv::Mat img;
	try {
		img = cv::imdecode(cv::Mat(1, int(bytes.size()), CV_8U, &bytes[0]), cv::IMREAD_UNCHANGED);
	} catch (const cv::Exception &) {
		img.release();
	}
	if (img.empty())
		return Status::error(EIO, path + ": cannot decode image (corrupt or not an image)");
	if (img.type() != CV_8UC3)
		return Status::error(EINVAL, path + ": must be 8-bit RGB, got " +
						     std::to_string(img.channels()) + " channel(s) of depth " +
						     std::to_string(img.depth()));
	if (img.size() != size)
		return Status::error(EINVAL, path + ": decoded size does not match its header");
	*ret = img;
	return {};
}

Status read_capture_set(const std::string &dir, CaptureSet *ret_set)
{
	struct stat st_dir;
	if (stat(dir.c_str(), &st_dir) < 0 || !S_ISDIR(st_dir.st_mode))
		return Status::error(ENOENT, dir + ": not a capture set directory");
	CaptureSet set;
	Status st = read_calibration(dir + "/calibration.yaml", &set.calibration);
	if (!st.ok())
		return st;
	const size_t n = set.calibration.cameras.size();

	std::string meta_path = dir + "/capture.json", meta_text;
	st = read_regular_file(meta_path, kMaxTextFileBytes, &meta_text);
	if (!st.ok())
		return st;
	st = parse_capture_meta(meta_text, meta_path, n, &set.meta);
	if (!st.ok())
		return st;

	size_t textures = 0;
	for (size_t i = 0; i < n; i++)
		textures += exists(dir + "/cam" + std::to_string(i) + "_texture.png");
	if (textures != 0 && textures != n)
		return Status::error(EINVAL, dir + ": texture frames must be given for all cameras or none (found " +
						     std::to_string(textures) + " of " + std::to_string(n) + ")");
	// Decoding the PNGs is most of the reading time and each file is independent: they are
	// decoded in parallel; the error reported is still the first file's in the sequential order.
	const size_t per_camera = textures ? 2 : 1;
	std::vector<cv::Mat> images(n * per_camera);
	std::vector<Status> status(n * per_camera);
	cv::parallel_for_(cv::Range(0, int(images.size())), [&](const cv::Range &r) {
		for (int k = r.start; k < r.end; ++k) {
			const size_t i = size_t(k) / per_camera;
			const bool texture = size_t(k) % per_camera == 1;
			status[size_t(k)] = read_frame(dir + "/cam" + std::to_string(i) + (texture ? "_texture.png" : ".png"),
						       set.calibration.cameras[i].size, &images[size_t(k)]);
		}
	});
	for (const Status &s : status)
		if (!s.ok())
			return s;
	for (size_t i = 0; i < n; i++) {
		set.frames.push_back(images[i * per_camera]);
		if (textures)
			set.textures.push_back(images[i * per_camera + 1]);
	}
	*ret_set = std::move(set);
	return {};
}

Status write_capture_set(const std::string &dir, const CaptureSet &set)
{
	const size_t n = set.calibration.cameras.size();
	if (set.frames.size() != n)
		return Status::error(EINVAL, "capture set has " + std::to_string(set.frames.size()) +
						     " frames for " + std::to_string(n) + " cameras");
	if (!set.textures.empty() && set.textures.size() != n)
		return Status::error(EINVAL, "capture set must have a texture frame per camera or none");
	if (set.meta.scan_id.empty() || set.meta.pattern_id.empty())
		return Status::error(EINVAL, "capture set needs a scan id and a pattern id");
	if (mkdir(dir.c_str(), 0755) < 0 && errno != EEXIST)
		return Status::error(errno, dir + ": cannot create: " + errno_text(errno));
	Status st = write_calibration(dir + "/calibration.yaml", set.calibration);
	for (size_t i = 0; i < n && st.ok(); i++) {
		if (set.frames[i].type() != CV_8UC3 || set.frames[i].size() != set.calibration.cameras[i].size)
			return Status::error(EINVAL, "frame " + std::to_string(i) +
							     " is not 8-bit RGB of the calibrated size");
		st = write_image_atomic(dir + "/cam" + std::to_string(i) + ".png", set.frames[i]);
		if (st.ok() && !set.textures.empty())
			st = write_image_atomic(dir + "/cam" + std::to_string(i) + "_texture.png",
						set.textures[i]);
	}
	if (!st.ok())
		return st;
	nlohmann::json j;
	j["scan_id"] = set.meta.scan_id;
	j["pattern"] = set.meta.pattern_id;
	if (!set.meta.timestamps_ns.empty())
		j["timestamps_ns"] = set.meta.timestamps_ns;
	if (!set.meta.exposure_us.empty())
		j["exposure_us"] = set.meta.exposure_us;
	if (!set.meta.trigger_report_json.empty()) {
		nlohmann::json report = nlohmann::json::parse(set.meta.trigger_report_json, nullptr, false);
		if (report.is_discarded())
			return Status::error(EINVAL, "trigger report is not valid JSON");
		j["trigger_report"] = report;
	}
	std::string text = j.dump(1) + "\n";
	return write_file_atomic(dir + "/capture.json", text.data(), text.size());
}

} // namespace facescan
