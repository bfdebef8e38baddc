// Capture-set reader/writer: round trip, and a clear error naming file and field per malformed case.
#include "capture/capture_set.hpp"

#include "cmocka.hpp"

#include <opencv2/imgcodecs.hpp>

#include <sys/stat.h>
#include <sys/types.h>
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

// A calibration.yaml for small_set()'s two cameras with cam0's K, T and size given as YAML text.
static std::string calibration_text(const std::string &k0, const std::string &t0, const std::string &size0,
				    const std::string &size1 = "[ 160, 120 ]")
{
	auto mat = [](const std::string &key, int rows, int cols, const std::string &data) {
		return key + ": !!opencv-matrix\n   rows: " + std::to_string(rows) + "\n   cols: " +
		       std::to_string(cols) + "\n   dt: d\n   data: [ " + data + " ]\n";
	};
	std::string y = "%YAML:1.0\n---\ncamera_count: 2\nunits: mm\n";
	for (int i = 0; i < 2; i++) {
		std::string c = "cam" + std::to_string(i);
		y += mat(c + "_K", 3, 3, i == 0 ? k0 : "400., 0., 80., 0., 400., 60., 0., 0., 1.");
		y += mat(c + "_dist", 1, 5, "0., 0., 0., 0., 0.");
		y += mat(c + "_R", 3, 3, "1., 0., 0., 0., 1., 0., 0., 0., 1.");
		y += mat(c + "_T", 3, 1, i == 0 ? t0 : "10., 0., 550.");
		y += c + "_size: " + (i == 0 ? size0 : size1) + "\n";
	}
	return y;
}

static const char *kK = "400., 0., 80., 0., 400., 60., 0., 0., 1.";
static const char *kT = "0., 0., 550.";

static Status read_calibration_text(const std::string &text, Calibration *ret)
{
	Dir d;
	write_text(d / "calibration.yaml", text);
	return read_calibration(d / "calibration.yaml", ret);
}

// Python's cv2.FileStorage writes a size as a 1x2 (or, transposed, 2x1) matrix, of int or of
// double; C++ writes a cv::Size as a sequence. All mean the same size.
static void size_as_sequence_or_matrix(void **)
{
	const char *forms[] = {
		"[ 160, 120 ]",
		"!!opencv-matrix\n   rows: 1\n   cols: 2\n   dt: i\n   data: [ 160, 120 ]",
		"!!opencv-matrix\n   rows: 2\n   cols: 1\n   dt: i\n   data: [ 160, 120 ]",
		"!!opencv-matrix\n   rows: 1\n   cols: 2\n   dt: d\n   data: [ 160., 120. ]",
		"!!opencv-matrix\n   rows: 2\n   cols: 1\n   dt: d\n   data: [ 1.6e+02, 1.2e+02 ]",
		"[ 160., 120. ]",
	};
	for (const char *f : forms) {
		Calibration c;
		Status st = read_calibration_text(calibration_text(kK, kT, f), &c);
		std::printf("  %s -> %s\n", f, st.ok() ? "ok" : st.message().c_str());
		assert_true(st.ok());
		assert_int_equal(c.cameras[0].size.width, 160);
		assert_int_equal(c.cameras[0].size.height, 120);
	}
}

static void implausible_sizes_refused(void **)
{
	struct Case {
		const char *size, *needle;
	} cases[] = {
		{"[ 160.5, 120 ]", "fractional"},
		{"!!opencv-matrix\n   rows: 1\n   cols: 2\n   dt: d\n   data: [ 160.25, 120. ]", "fractional"},
		{"[ -160, 120 ]", "plausible"},
		{"[ 0, 120 ]", "plausible"},
		{"[ 100000, 120 ]", "plausible"},
		{"[ 160, 120, 3 ]", "[width, height]"},
		{"!!opencv-matrix\n   rows: 2\n   cols: 2\n   dt: i\n   data: [ 160, 120, 1, 1 ]", "1x2"},
		{"\"160x120\"", "[width, height]"},
		{"[ .nan, 120 ]", "cam0_size"},
	};
	for (const Case &k : cases) {
		Calibration c;
		Status st = read_calibration_text(calibration_text(kK, kT, k.size), &c);
		std::printf("  %s -> %s\n", k.size, st.message().c_str());
		assert_int_equal(st.code(), -EINVAL);
		assert_non_null(std::strstr(st.message().c_str(), "cam0_size"));
		assert_non_null(std::strstr(st.message().c_str(), k.needle));
	}
	// Sides each fine, the area not: 10000x10000 is 100 MP (300 MB a frame).
	Calibration c;
	Status st = read_calibration_text(calibration_text(kK, kT, "[ 10000, 10000 ]", "[ 10000, 10000 ]"), &c);
	std::printf("  10000x10000 -> %s\n", st.message().c_str());
	assert_int_equal(st.code(), -EINVAL);
	assert_non_null(std::strstr(st.message().c_str(), "MP"));
}

// Focal lengths and translations a typo or a unit error makes: refused, naming the field.
static void implausible_geometry_refused(void **)
{
	struct Case {
		std::string k, t;
		const char *needle;
	} cases[] = {
		{"1e308, 0., 80., 0., 1e308, 60., 0., 0., 1.", kT, "focal length"},
		{"1e-300, 0., 80., 0., 1e-300, 60., 0., 0., 1.", kT, "focal length"},
		{"400., 0., 80., 0., 400., 60., 0., 0., 1.", "1e308, 0., 550.", "10 m"},
		{"400., 0., 80., 0., 400., 60., 0., 0., 1.", "0., 0., 55000.", "10 m"},
		{"400., 0., 8000., 0., 400., 60., 0., 0., 1.", kT, "principal point"},
		{"400., 0., 80., 0., 400., 60., 0., 1., 1.", kT, "camera matrix"},
	};
	for (const Case &k : cases) {
		Calibration c;
		Status st = read_calibration_text(calibration_text(k.k, k.t, "[ 160, 120 ]"), &c);
		std::printf("  K=[%s] T=[%s] -> %s\n", k.k.c_str(), k.t.c_str(), st.message().c_str());
		assert_int_equal(st.code(), -EINVAL);
		assert_non_null(std::strstr(st.message().c_str(), k.needle));
	}
	Calibration c;
	assert_true(read_calibration_text(calibration_text(kK, kT, "[ 160, 120 ]"), &c).ok());
}

// Hostile files: each is a clear error, never a crash, a hang or a huge allocation.
static void hostile_files_refused(void **)
{
	{
		Dir d; // ~40,000 nested '[' overflowed OpenCV's recursive parser (SIGSEGV)
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		write_text(d / "calibration.yaml", "%YAML:1.0\n---\ncamera_count: " + std::string(40000, '[') + "\n");
		expect_error(d, -EINVAL, {"calibration.yaml", "nested"});
	}
	{
		Dir d; // a '#' comment or a quoted ']' does not hide real nesting
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		std::string y = "%YAML:1.0\n---\nx: ";
		for (int i = 0; i < 100; i++)
			y += "[ \"]\", ";
		write_text(d / "calibration.yaml", y + "\n");
		expect_error(d, -EINVAL, {"calibration.yaml", "nested"});
	}
	{
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		write_text(d / "calibration.yaml", "%YAML:1.0\n# " + std::string(2 << 20, 'x') + "\n");
		expect_error(d, -EFBIG, {"calibration.yaml", "bytes"});
	}
	{
		Dir d; // a JSON this deep crashed the recursive dump of trigger_report
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		write_text(d / "capture.json", "{\"scan_id\": \"a\", \"pattern\": \"p\", \"trigger_report\": " +
						       std::string(100000, '[') + std::string(100000, ']') + "}");
		expect_error(d, -EINVAL, {"capture.json", "nested"});
	}
	{
		Dir d; // a directory named capture.json threw std::ios_base::failure (SIGABRT)
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		unlink((d / "capture.json").c_str());
		assert_int_equal(mkdir((d / "capture.json").c_str(), 0755), 0);
		expect_error(d, -EINVAL, {"capture.json", "not a regular file"});
	}
	{
		Dir d; // a FIFO named calibration.yaml or cam0.png blocked the reader forever
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		unlink((d / "cam0.png").c_str());
		assert_int_equal(mkfifo((d / "cam0.png").c_str(), 0644), 0);
		alarm(20); // a hang fails the test instead of stalling the suite
		expect_error(d, -EINVAL, {"cam0.png", "not a regular file"});
		unlink((d / "calibration.yaml").c_str());
		assert_int_equal(mkfifo((d / "calibration.yaml").c_str(), 0644), 0);
		expect_error(d, -EINVAL, {"calibration.yaml", "not a regular file"});
		alarm(0);
	}
	{
		// A PNG whose header claims 20000x20000 (its pixel data cut short): refused for its
		// size before decoding, not decoded into 1.2 GB and then found corrupt.
		Dir d;
		assert_true(write_capture_set(d.path, small_set(false)).ok());
		std::vector<uchar> png;
		assert_true(cv::imencode(".png", cv::Mat(120, 160, CV_8UC3, cv::Scalar::all(0)), png));
		auto put32 = [&](size_t at, uint32_t v) {
			for (int b = 0; b < 4; b++)
				png[at + size_t(b)] = uchar(v >> (24 - 8 * b));
		};
		put32(16, 20000);
		put32(20, 20000);
		std::ofstream(d / "cam0.png", std::ios::binary).write(reinterpret_cast<char *>(png.data()), long(png.size()));
		expect_error(d, -EINVAL, {"cam0.png", "20000x20000", "does not match"});
	}
}

// What tests/host/fuzz_calibration found (the inputs are also its seeds,
// tests/host/fuzz_calibration_seeds/): each aborted or hung the reader, and is now -EINVAL
// naming the file. alarm(): a hang fails the test instead of stalling the suite.
static void fuzzer_findings_refused(void **)
{
	struct Case {
		std::string text;
		const char *needle;
	} cases[] = {
		// OpenCV allocated the declared 1e9 x 1e9 doubles (8 EB) before counting the data.
		{"%YAML:1.0\n---\ncamera_count: 2\nunits: mm\ncam0_K: !!opencv-matrix\n   rows: 1000000000\n"
		 "   cols: 1000000000\n   dt: d\n   data: [ 1. ]\n",
		 "declares 1000000000x1000000000"},
		{calibration_text(kK, kT, "!!opencv-matrix\n   rows: 20000\n   cols: 20000\n   dt: d\n   data: [ 1., 2. ]"),
		 "cam0_size"},
		{"%YAML:1.0\n---\ncamera_count: 2\nunits: mm\ncam0_K: !!opencv-matrix\n   sizes: [ 3, 3, 1 ]\n"
		 "   dt: d\n   data: [ 1. ]\n",
		 "unexpected key 'sizes'"},
		{"%YAML:1.0\n---\ncamera_count: 2\nunits: mm\ncam0_K: !!opencv-matrix\n   rows: 3\n   cols: 3\n"
		 "   dt: \"2d\"\n   data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]\n",
		 "one channel"},
		// fs["camera_count"] on a root sequence threw cv::Exception (std::terminate).
		{"%YAML:1.0\n---\n- 1\n", "top level"},
		// OpenCV's parser threw std::length_error (std::terminate): an empty key at the very end.
		{"%YAML:1.0\n---\na:\n s:1\n :", "not a readable"},
		// OpenCV's parser never returned.
		{"%YAML:1.0\n---\n  u: m\n---\n- 1\n", "indented"},
		{"%YAML:1.0\n---\nu: m\n...\n- 1\n", "more than one YAML document"},
		{"%YAML:1.0\n---\nu: m\n---\n- 1\n", "more than one YAML document"},
		{"%YAML:1.0\n  u: m\n---\n- 1\n", "indented"},
		{"%YAML:1.0\n---\n u: m\n- 1\n- 1\n", "indented"},
		{"%YAML:1.0\n--- u: m\n- 1\n- 1\n", "'---' line"},
	};
	alarm(20);
	for (const Case &k : cases) {
		Calibration c;
		Status st = read_calibration_text(k.text, &c);
		std::printf("  -> %s\n", st.message().c_str());
		assert_int_equal(st.code(), -EINVAL);
		assert_non_null(std::strstr(st.message().c_str(), "calibration.yaml"));
		assert_non_null(std::strstr(st.message().c_str(), k.needle));
		// The same from memory (the fuzz target's entry point).
		Status mem = parse_calibration(k.text, "mem.yaml", &c);
		assert_int_equal(mem.code(), -EINVAL);
		assert_non_null(std::strstr(mem.message().c_str(), k.needle));
	}
	alarm(0);
	// The layout checks leave what OpenCV writes alone: a written calibration parses from memory.
	Dir d;
	CaptureSet set = small_set(false);
	assert_true(write_calibration(d / "calibration.yaml", set.calibration).ok());
	std::string text;
	assert_true(read_regular_file(d / "calibration.yaml", 1 << 20, &text).ok());
	Calibration back;
	assert_true(parse_calibration(text, "mem.yaml", &back).ok());
	assert_int_equal(back.cameras.size(), 2);
	assert_true(back.cameras[1].size == cv::Size(160, 120));
	CaptureMeta meta;
	assert_true(parse_capture_meta("{\"scan_id\": \"s\", \"pattern\": \"p\", \"exposure_us\": [1, 2]}",
				       "mem.json", 2, &meta).ok());
	assert_int_equal(meta.exposure_us.size(), 2);
	Status st = parse_capture_meta("{\"scan_id\": \"s\", \"pattern\": \"p\", \"exposure_us\": [1, 2]}",
				       "mem.json", 3, &meta);
	assert_int_equal(st.code(), -EINVAL);
	assert_non_null(std::strstr(st.message().c_str(), "mem.json"));
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
		cmocka_unit_test(size_as_sequence_or_matrix),
		cmocka_unit_test(implausible_sizes_refused),
		cmocka_unit_test(implausible_geometry_refused),
		cmocka_unit_test(hostile_files_refused),
		cmocka_unit_test(fuzzer_findings_refused),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
