// Capture-set reader/writer: round trip, and a clear error naming file and field per malformed case.
#include "capture/capture_set.hpp"

#include "cmocka.hpp"

#include <opencv2/imgcodecs.hpp>

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

using namespace facescan;

static CaptureSet small_set(bool textures)
{
	CaptureSet set;
	for (int i = 0; i < 2; i++) {
		CameraModel cam;
		cam.K = cv::Matx33d(400, 0, 80, 0, 400, 60, 0, 0, 1);
		cam.dist = {-0.1, 0.01, 0.001, -0.001, 0};
		double a = (i ? -0.3 : 0.3);
		cam.R = cv::Matx33d(std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a));
		cam.T = {i * 10.0, 1.5, 550};
		cam.size = {160, 120};
		set.calibration.cameras.push_back(cam);
		cv::Mat frame(120, 160, CV_8UC3);
		cv::randu(frame, 0, 255);
		set.frames.push_back(frame);
		if (textures)
			set.textures.push_back(frame / 2);
	}
	set.meta.scan_id = "scan-0001";
	set.meta.pattern_id = "fs-l3-14x19-s2";
	set.meta.timestamps_ns = {1000, 1010};
	set.meta.trigger_report_json = R"({"edges":[1,1,1,1]})";
	return set;
}

struct Dir {
	std::string path;
	Dir()
	{
		char t[] = "/tmp/facescan-capture-XXXXXX";
		path = mkdtemp(t);
	}
	~Dir()
	{
		std::string cmd = "rm -rf '" + path + "'";
		if (system(cmd.c_str()) != 0)
			std::fprintf(stderr, "cannot remove %s\n", path.c_str());
	}
	std::string operator/(const std::string &f) const { return path + "/" + f; }
};

static void write_text(const std::string &path, const std::string &text)
{
	std::ofstream(path) << text;
}

static void replace_in_file(const std::string &path, const std::string &from, const std::string &to)
{
	std::ifstream in(path);
	std::string s((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
	size_t at = s.find(from);
	assert_true(at != std::string::npos);
	s.replace(at, from.size(), to);
	write_text(path, s);
}

// Expects read_capture_set to fail with `code` and a message containing every `needle`.
static void expect_error(const Dir &d, int code, std::initializer_list<const char *> needles)
{
	CaptureSet out;
	Status st = read_capture_set(d.path, &out);
	std::printf("  -> %s\n", st.message().c_str());
	assert_int_equal(st.code(), code);
	for (const char *n : needles)
		assert_non_null(std::strstr(st.message().c_str(), n));
}

static void round_trip(void **)
{
	Dir d;
	CaptureSet set = small_set(true);
	assert_true(write_capture_set(d.path, set).ok());
	CaptureSet back;
	Status st = read_capture_set(d.path, &back);
	assert_true(st.ok());
	assert_int_equal(back.frames.size(), 2);
	assert_int_equal(back.textures.size(), 2);
	for (int i = 0; i < 2; i++) {
		assert_int_equal(cv::norm(back.frames[size_t(i)], set.frames[size_t(i)], cv::NORM_INF), 0);
		const CameraModel &a = set.calibration.cameras[size_t(i)], &b = back.calibration.cameras[size_t(i)];
		assert_true(cv::norm(a.K - b.K) < 1e-12 && cv::norm(a.R - b.R) < 1e-12);
		assert_true(cv::norm(a.T - b.T) < 1e-12 && cv::norm(a.dist - b.dist) < 1e-12);
		assert_true(a.size == b.size);
	}
	assert_string_equal(back.meta.scan_id.c_str(), "scan-0001");
	assert_string_equal(back.meta.pattern_id.c_str(), "fs-l3-14x19-s2");
	assert_int_equal(back.meta.timestamps_ns.size(), 2);
	assert_non_null(std::strstr(back.meta.trigger_report_json.c_str(), "edges"));
	// No temporary files left behind by the atomic writes.
	std::string cmd = "ls -a '" + d.path + "' | grep -q tmp";
	assert_int_not_equal(system(cmd.c_str()), 0);
}

static void textures_are_optional(void **)
{
	Dir d;
	assert_true(write_capture_set(d.path, small_set(false)).ok());
	CaptureSet back;
	assert_true(read_capture_set(d.path, &back).ok());
	assert_true(back.textures.empty());
}

static void malformed_sets_name_file_and_field(void **)
{
	{
		CaptureSet out;
		assert_int_equal(read_capture_set("/nonexistent/set", &out).code(), -ENOENT);
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		unlink((d / "calibration.yaml").c_str());
		expect_error(d, -ENOENT, {"calibration.yaml", "missing"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		write_text(d / "calibration.yaml", "this: [is not: yaml");
		expect_error(d, -EINVAL, {"calibration.yaml"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		replace_in_file(d / "calibration.yaml", "camera_count: 2", "camera_count: two");
		expect_error(d, -EINVAL, {"calibration.yaml", "camera_count"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		replace_in_file(d / "calibration.yaml", "cam1_K", "cam1_Kx");
		expect_error(d, -EINVAL, {"calibration.yaml", "cam1_K"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		replace_in_file(d / "calibration.yaml", "units: mm", "units: inch");
		expect_error(d, -EINVAL, {"units"});
	}
	{
		Dir d; // R scaled by 2 is not a rotation
		CaptureSet set = small_set(false);
		assert_true(write_capture_set(d.path, set).ok());
		replace_in_file(d / "calibration.yaml", "cam0_R: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ ",
				"cam0_R: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 2., 0., 0., 0., 2., 0., 0., 0., 2., ");
		CaptureSet out;
		Status st = read_capture_set(d.path, &out);
		assert_int_equal(st.code(), -EINVAL);
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		unlink((d / "cam1.png").c_str());
		expect_error(d, -ENOENT, {"cam1.png"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		write_text(d / "cam0.png", "\x89PNG garbage");
		expect_error(d, -EIO, {"cam0.png", "decode"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		cv::imwrite(d / "cam0.png", cv::Mat(60, 80, CV_8UC3, cv::Scalar::all(9)));
		expect_error(d, -EINVAL, {"cam0.png", "does not match"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		cv::imwrite(d / "cam1.png", cv::Mat(120, 160, CV_8UC1, cv::Scalar::all(9)));
		expect_error(d, -EINVAL, {"cam1.png", "8-bit RGB"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(true)).ok());
		unlink((d / "cam1_texture.png").c_str());
		expect_error(d, -EINVAL, {"texture"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		unlink((d / "capture.json").c_str());
		expect_error(d, -ENOENT, {"capture.json"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		write_text(d / "capture.json", "{\"scan_id\": \"a\"}");
		expect_error(d, -EINVAL, {"capture.json", "'pattern'"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		write_text(d / "capture.json", "{\"scan_id\": \"a\", \"pattern\": \"p\", \"timestamps_ns\": [1]}");
		expect_error(d, -EINVAL, {"capture.json", "timestamps_ns"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		write_text(d / "capture.json", "{not json");
		expect_error(d, -EINVAL, {"capture.json", "JSON"});
	}
}

static void writer_refuses_inconsistent_sets(void **)
{
	Dir d;
	CaptureSet set = small_set(true);
	set.textures.pop_back();
	assert_int_equal(write_capture_set(d.path, set).code(), -EINVAL);
	set = small_set(false);
	set.meta.pattern_id.clear();
	assert_int_equal(write_capture_set(d.path, set).code(), -EINVAL);
	// An unwritable destination is an error with errno, not a crash.
	assert_true(write_file_atomic("/nonexistent-dir/x", "a", 1).code() == -ENOENT);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(round_trip),
		cmocka_unit_test(textures_are_optional),
		cmocka_unit_test(malformed_sets_name_file_and_field),
		cmocka_unit_test(writer_refuses_inconsistent_sets),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
