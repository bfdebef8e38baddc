// The capture set: what the booth records for one scan, in memory and on disk.
// On-disk format: docs/capture-format.md. The simulator and the camera backends write it;
// recon, calibrate and the daemon read it.
#pragma once

#include "common/status.hpp"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace facescan {

/// One camera of the calibration. World → camera: x_cam = R * x_world + T (mm).
struct CameraModel {
	cv::Matx33d K = cv::Matx33d::eye();
	cv::Vec<double, 5> dist = {0, 0, 0, 0, 0}; // k1 k2 p1 p2 k3 (OpenCV's 5-coefficient model)
	cv::Matx33d R = cv::Matx33d::eye();
	cv::Vec3d T = {0, 0, 0};
	cv::Size size;
	/// Camera centre in world coordinates: -R^T T.
	cv::Vec3d centre() const { return -(R.t() * T); }
};

struct Calibration {
	std::vector<CameraModel> cameras;
	std::string units = "mm";
	std::string id; // optional: names the calibration run (recorded in scan metadata)
};

struct CaptureMeta {
	std::string scan_id;
	std::string pattern_id;
	std::vector<double> timestamps_ns;	// per camera, optional (empty when unknown)
	std::vector<double> exposure_us;	// per camera, optional
	std::string trigger_report_json;	// the firmware's report as a JSON text, optional
};

struct CaptureSet {
	Calibration calibration;
	std::vector<cv::Mat> frames;	// per camera, 8-bit BGR (OpenCV order), pattern lit
	std::vector<cv::Mat> textures;	// per camera, 8-bit BGR, projectors off; may be empty
	CaptureMeta meta;
};

/// Reads calibration.yaml. Errors name the file and the field (-ENOENT, -EINVAL).
Status read_calibration(const std::string &path, Calibration *ret_calibration);
/// Parses the text of a calibration.yaml (what read_calibration does once it has the bytes);
/// `name` is the file the errors name. -EINVAL; *ret_calibration untouched on failure.
Status parse_calibration(const std::string &text, const std::string &name,
			 Calibration *ret_calibration);
/// Parses the text of a capture.json for a set of `camera_count` cameras; `name` is the file
/// the errors name. -EINVAL; *ret_meta untouched on failure.
Status parse_capture_meta(const std::string &text, const std::string &name, size_t camera_count,
			  CaptureMeta *ret_meta);
/// Writes calibration.yaml atomically (temp file + rename).
Status write_calibration(const std::string &path, const Calibration &calibration);

/// Reads a capture set directory and checks it for consistency: every camera's frame exists,
/// decodes, is 8-bit 3-channel and matches its calibrated size; textures all or none.
Status read_capture_set(const std::string &dir, CaptureSet *ret_set);
/// Writes a capture set into `dir` (created if missing). Each file is written atomically.
Status write_capture_set(const std::string &dir, const CaptureSet &set);

/// Reads a whole file of at most `max_bytes`. Opened non-blocking and refused unless it is a
/// regular file, so a FIFO or a device under that name cannot hang the reader nor a huge file
/// balloon it. -ENOENT missing, -EINVAL not a regular file, -EFBIG too large, -errno.
Status read_regular_file(const std::string &path, size_t max_bytes, std::string *ret);
/// The same checks without reading (never opens: a FIFO cannot block it), for readers that open
/// the file themselves (OpenCV's imread, assimp).
Status check_regular_file(const std::string &path, size_t max_bytes);
/// Writes bytes to `path` atomically: temp file in the same directory, fsync, rename, fsync dir.
Status write_file_atomic(const std::string &path, const void *data, size_t size);
/// Encodes an image by the path's extension and writes it atomically.
Status write_image_atomic(const std::string &path, const cv::Mat &image);

} // namespace facescan
