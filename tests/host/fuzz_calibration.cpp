// libFuzzer target (make fuzz): the capture set's calibration.yaml reader, parse_calibration()
// (read_calibration() once it has the file's bytes), on OpenCV's FileStorage YAML parser.
//
// The input is the whole text of a calibration.yaml. Invariants besides "no crash, no hang, no
// ballooning" (ASan/UBSan, -rss_limit_mb, -timeout): a refusal names the file; an accepted
// calibration has 2..16 cameras, each with a plausible image size, finite intrinsics and a
// rotation. Seeds: tests/host/fuzz_calibration_seeds/.
#include "capture/capture_set.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "fuzz_check.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	const std::string text(reinterpret_cast<const char *>(data), size);
	const std::string name = "fuzz/calibration.yaml";
	facescan::Calibration c;
	c.id = "untouched";
	facescan::Status st = facescan::parse_calibration(text, name, &c);
	if (!st.ok()) {
		CHECK(st.code() < 0);
		CHECK(st.message().compare(0, name.size() + 1, name + ":") == 0);
		CHECK(c.id == "untouched" && c.cameras.empty());
		return 0;
	}
	CHECK(c.cameras.size() >= 2 && c.cameras.size() <= 16);
	CHECK(c.units == "mm");
	for (const facescan::CameraModel &cam : c.cameras) {
		CHECK(cam.size.width >= 1 && cam.size.width <= 10000);
		CHECK(cam.size.height >= 1 && cam.size.height <= 10000);
		for (int k = 0; k < 9; k++)
			CHECK(std::isfinite(cam.K.val[k]) && std::isfinite(cam.R.val[k]));
		for (int k = 0; k < 5; k++)
			CHECK(std::isfinite(cam.dist[k]));
		for (int k = 0; k < 3; k++)
			CHECK(std::isfinite(cam.T[k]));
		CHECK(cam.K(0, 0) > 0 && cam.K(1, 1) > 0 && cam.K(2, 2) == 1.0);
		CHECK(cv::norm(cam.R * cam.R.t() - cv::Matx33d::eye()) <= 1e-6);
	}
	return 0;
}
