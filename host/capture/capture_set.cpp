// Capture-set reader and writer. Format: docs/capture-format.md.
#include "capture/capture_set.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <fstream>

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

std::string cam_key(int i, const char *field)
{
	return "cam" + std::to_string(i) + "_" + field;
}

// Reads a real matrix node of exactly rows x cols (either orientation for vectors).
Status read_matrix(const cv::FileStorage &fs, const std::string &file, const std::string &key,
		   int rows, int cols, cv::Mat *ret)
{
	cv::FileNode node = fs[key];
	if (node.empty())
		return Status::error(EINVAL, file + ": missing field '" + key + "'");
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
		std::string who = file + ": camera " + std::to_string(i);
		if (cam.K(0, 0) <= 0 || cam.K(1, 1) <= 0 || cam.K(2, 2) != 1.0)
			return Status::error(EINVAL, who + ": field '" + cam_key(int(i), "K") +
							     "' is not a camera matrix");
		cv::Matx33d should_be_eye = cam.R * cam.R.t();
		if (cv::norm(should_be_eye - cv::Matx33d::eye()) > 1e-6 || cv::determinant(cam.R) < 0)
			return Status::error(EINVAL, who + ": field '" + cam_key(int(i), "R") +
							     "' is not a rotation");
		if (cam.size.width <= 0 || cam.size.height <= 0 || cam.size.width > 20000 ||
		    cam.size.height > 20000)
			return Status::error(EINVAL, who + ": field '" + cam_key(int(i), "size") +
							     "' is not a plausible image size");
	}
	return {};
}

} // namespace

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
	if (!exists(path))
		return Status::error(ENOENT, path + ": missing");
	cv::FileStorage fs;
	try {
		fs.open(path, cv::FileStorage::READ);
	} catch (const cv::Exception &) {
		return Status::error(EINVAL, path + ": not a readable OpenCV YAML file");
	}
	if (!fs.isOpened())
		return Status::error(EINVAL, path + ": not a readable OpenCV YAML file");
	Calibration calib;
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
		calib.id = std::string(fs["id"]);
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
		cv::FileNode size = fs[cam_key(i, "size")];
		if (size.empty() || !size.isSeq() || size.size() != 2 || !size[0].isInt() ||
		    !size[1].isInt())
			return Status::error(EINVAL, path + ": field '" + cam_key(i, "size") +
							     "' must be [width, height]");
		cam.size = cv::Size(int(size[0]), int(size[1]));
		calib.cameras.push_back(cam);
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

static Status read_frame(const std::string &path, const cv::Size &size, cv::Mat *ret)
{
	if (!exists(path))
		return Status::error(ENOENT, path + ": missing");
	cv::Mat img;
	try {
		img = cv::imread(path, cv::IMREAD_UNCHANGED);
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
		return Status::error(EINVAL, path + ": size " + std::to_string(img.cols) + "x" +
						     std::to_string(img.rows) +
						     " does not match the calibration's " +
						     std::to_string(size.width) + "x" +
						     std::to_string(size.height));
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

	std::string meta_path = dir + "/capture.json";
	std::ifstream in(meta_path);
	if (!in)
		return Status::error(ENOENT, meta_path + ": missing");
	nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
	if (j.is_discarded() || !j.is_object())
		return Status::error(EINVAL, meta_path + ": not a JSON object");
	for (const char *key : {"scan_id", "pattern"})
		if (!j.contains(key) || !j[key].is_string() || j[key].get<std::string>().empty())
			return Status::error(EINVAL, meta_path + ": missing or invalid field '" +
							     key + "'");
	set.meta.scan_id = j["scan_id"].get<std::string>();
	set.meta.pattern_id = j["pattern"].get<std::string>();
	for (auto [key, out] : {std::pair{"timestamps_ns", &set.meta.timestamps_ns},
				std::pair{"exposure_us", &set.meta.exposure_us}}) {
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
		set.meta.trigger_report_json = j["trigger_report"].dump();

	size_t textures = 0;
	for (size_t i = 0; i < n; i++)
		textures += exists(dir + "/cam" + std::to_string(i) + "_texture.png");
	if (textures != 0 && textures != n)
		return Status::error(EINVAL, dir + ": texture frames must be given for all cameras or none (found " +
						     std::to_string(textures) + " of " + std::to_string(n) + ")");
	for (size_t i = 0; i < n; i++) {
		const cv::Size size = set.calibration.cameras[i].size;
		cv::Mat frame;
		st = read_frame(dir + "/cam" + std::to_string(i) + ".png", size, &frame);
		if (!st.ok())
			return st;
		set.frames.push_back(frame);
		if (textures) {
			st = read_frame(dir + "/cam" + std::to_string(i) + "_texture.png", size, &frame);
			if (!st.ok())
				return st;
			set.textures.push_back(frame);
		}
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
