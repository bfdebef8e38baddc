// The reconstruction in its own process: the child's limits (deadline, RLIMIT_AS) hold, its
// crash, timeout and memory exhaustion become failed scans with the reason and the capture kept
// for an offline retry, and the daemon serving the booth lives through all of them. The real
// worker (`facescan recon`) reconstructs a simulated set through it.
#include "capture/capture_set.hpp"
#include "daemon/client.hpp"
#include "daemon/daemon.hpp"
#include "daemon/driver_cameras.hpp"
#include "daemon/log.hpp"
#include "daemon/make_backends.hpp"
#include "daemon/worker_recon.hpp"
#include "mesh_io/mesh_io.hpp"
#include "sim/sim.hpp"

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <sys/stat.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

using namespace facescan::daemon;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

struct TmpDir {
	std::string path;
	TmpDir()
	{
		char t[] = "/tmp/facescan-worker-XXXXXX";
		path = mkdtemp(t);
	}
	~TmpDir()
	{
		std::string cmd = "rm -rf '" + path + "'";
		if (std::system(cmd.c_str()) != 0)
			std::fprintf(stderr, "cannot remove %s\n", path.c_str());
	}
};

// A worker program: a shell script standing in for `facescan recon` that misbehaves.
std::string script(const TmpDir &d, const std::string &name, const std::string &body)
{
	const std::string path = d.path + "/" + name;
	std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
	chmod(path.c_str(), 0755);
	return path;
}

// A tiny valid capture set of 2 cameras (64x48 frames, as the fake cameras make).
facescan::Calibration small_calibration()
{
	facescan::Calibration cal;
	for (int i = 0; i < 2; i++) {
		facescan::CameraModel cam;
		cam.K = cv::Matx33d(80, 0, 32, 0, 80, 24, 0, 0, 1);
		cam.T = {i * -100.0, 0, 500};
		cam.size = {64, 48};
		cal.cameras.push_back(cam);
	}
	return cal;
}

std::string write_small_set(const TmpDir &d)
{
	facescan::CaptureSet set;
	set.calibration = small_calibration();
	for (int i = 0; i < 2; i++)
		set.frames.push_back(cv::Mat(48, 64, CV_8UC3, cv::Scalar(10, 20, 30 + i)));
	set.meta.scan_id = "abc";
	set.meta.pattern_id = "fs-l3-14x19-s2";
	const std::string dir = d.path + "/set";
	assert_true(facescan::write_capture_set(dir, set).ok());
	return dir;
}

void rm_rf(const std::string &path)
{
	std::string cmd = "rm -rf '" + path + "'";
	if (std::system(cmd.c_str()) != 0)
		std::fprintf(stderr, "cannot remove %s\n", path.c_str());
}

bool no_child_left()
{
	int st;
	return waitpid(-1, &st, WNOHANG) < 0 && errno == ECHILD;
}

} // namespace

static void test_child_limits(void **)
{
	TmpDir d;
	ChildResult r;
	// the address-space limit is the child's, in KiB as the shell reports it
	assert_true(run_with_limits({"/bin/sh", "-c", "ulimit -v >&2"}, 5000, 123, &r).ok());
	assert_int_equal(r.exit_code, 0);
	assert_int_equal(std::atoi(r.stderr_tail.c_str()), 123 * 1024);
	// a crash is its signal
	assert_true(run_with_limits({"/bin/sh", "-c", "kill -SEGV $$"}, 5000, 0, &r).ok());
	assert_int_equal(r.signal, SIGSEGV);
	assert_false(r.timed_out);
	// a hang is killed at the deadline, and reaped; stderr that never closes changes nothing
	auto t0 = Clock::now();
	assert_true(run_with_limits({"/bin/sh", "-c", "echo working >&2; exec sleep 30"}, 300, 0, &r).ok());
	double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
	std::printf("  hung child killed after %.0f ms\n", ms);
	assert_true(r.timed_out);
	assert_true(ms >= 290 && ms < 2000);
	assert_non_null(std::strstr(r.stderr_tail.c_str(), "working"));
	// a child that closes stderr and runs on is still bounded by the deadline
	t0 = Clock::now();
	assert_true(run_with_limits({"/bin/sh", "-c", "exec 2>&-; exec sleep 30"}, 300, 0, &r).ok());
	assert_true(r.timed_out);
	ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
	assert_true(ms < 2000);
	// a flood of stderr is kept to its tail
	assert_true(run_with_limits({"/bin/sh", "-c", "yes line | head -c 1000000 >&2; echo LAST >&2; exit 3"}, 10000, 0, &r).ok());
	assert_int_equal(r.exit_code, 3);
	assert_true(r.stderr_tail.size() <= 16 * 1024);
	assert_non_null(std::strstr(r.stderr_tail.c_str(), "LAST"));
	// a program that does not exist
	assert_true(run_with_limits({d.path + "/no-such-worker"}, 5000, 0, &r).ok());
	assert_int_equal(r.exit_code, 127);
	assert_true(no_child_left());
}

static void expect_failure(const WorkerParams &p, const facescan::daemon::Capture &c, int code,
			   const char *needle, const std::string &kept)
{
	WorkerReconstructor w(p);
	ReconOutput out;
	out.vertices = -7;
	facescan::Status s = w.run(c, &out);
	std::printf("  -> %s\n", s.message().c_str());
	assert_int_equal(s.code(), code);
	assert_non_null(std::strstr(s.message().c_str(), needle));
	assert_non_null(std::strstr(s.message().c_str(), ("capture kept in " + kept).c_str()));
	assert_int_equal(out.vertices, -7);
	// the kept set is one `facescan recon` can read again
	facescan::CaptureSet back;
	facescan::Status r = facescan::read_capture_set(kept, &back);
	if (!r.ok())
		fail_msg("kept set unreadable: %s", r.message().c_str());
	// nothing of the run is left in the work directory
	std::string cmd = "ls -A '" + p.spool_dir + "/work' | grep -q .";
	assert_int_not_equal(std::system(cmd.c_str()), 0);
	assert_true(no_child_left());
}

static void test_worker_failures_keep_the_capture(void **)
{
	TmpDir d;
	WorkerParams p;
	p.spool_dir = d.path + "/spool";
	mkdir(p.spool_dir.c_str(), 0750);
	p.memory_mb = 0;
	Capture c;
	c.source_dir = write_small_set(d);
	c.scan_name = "20260101T000000Z_abc";
	const std::string kept = p.spool_dir + "/captures/" + c.scan_name;

	p.program = script(d, "crash", "kill -SEGV $$");
	expect_failure(p, c, -ECHILD, "crashed (signal 11", kept);
	rm_rf(kept);

	p.program = script(d, "hang", "exec sleep 30");
	p.timeout_ms = 300;
	expect_failure(p, c, -ETIMEDOUT, "killed after 300 ms (recon_timeout_ms)", kept);
	p.timeout_ms = 10000;
	rm_rf(kept);

	// A real allocation beyond the limit (python's MemoryError), reported as what it is.
	p.program = script(d, "hog", "python3 -c 'bytearray(400 << 20)' 2>&1 | grep -q MemoryError "
				     "&& { echo 'std::bad_alloc' >&2; exit 134; }; exit 0");
	p.memory_mb = 200;
	if (std::system("python3 -c 'pass' 2>/dev/null") == 0)
		expect_failure(p, c, -ENOMEM, "out of memory (recon_memory_mb = 200)", kept);
	else
		std::printf("  (no python3: memory case not run)\n");
	p.memory_mb = 0;
	rm_rf(kept);

	p.program = script(d, "refuse", "echo 'facescan recon: DIR: camera 1: no pattern found' >&2; exit 1");
	expect_failure(p, c, -EIO, "camera 1: no pattern found", kept);
	rm_rf(kept);

	p.program = script(d, "silent", "exit 0"); // "succeeded" without writing its outputs
	expect_failure(p, c, -ENOENT, "mesh.drc", kept);
}

// The simulated booth leaves its set in the daemon's scratch (<spool>/work/), where the next scan
// overwrites it: the worker makes it the scan's (<spool>/captures/<scan>) before it runs, so a
// crash, or the daemon killed mid-reconstruction (found by the soak), keeps it; release()
// removes it once the scan is committed, unless keep_captures.
static void test_scratch_set_becomes_the_scans(void **)
{
	TmpDir d;
	WorkerParams p;
	p.spool_dir = d.path + "/spool";
	mkdir(p.spool_dir.c_str(), 0750);
	mkdir((p.spool_dir + "/work").c_str(), 0750);
	p.memory_mb = 0;
	const std::string outside = write_small_set(d);
	const std::string scratch = p.spool_dir + "/work/simulated-capture";
	assert_int_equal(std::system(("cp -r '" + outside + "' '" + scratch + "'").c_str()), 0);
	Capture c;
	c.source_dir = scratch;
	c.scan_name = "20260101T000000Z_abd";
	const std::string kept = p.spool_dir + "/captures/" + c.scan_name;
	// A worker that is killed while it runs (as the daemon around it would be).
	p.program = script(d, "killed", "test -f \"$2/calibration.yaml\" || exit 3; kill -KILL $$");
	expect_failure(p, c, -ECHILD, "crashed (signal 9", kept);
	struct stat st;
	assert_int_equal(stat((kept + "/calibration.yaml").c_str(), &st), 0);
	assert_int_equal(stat((kept + "/cam1.png").c_str(), &st), 0);
	assert_int_not_equal(stat(scratch.c_str(), &st), 0); // moved, not copied

	WorkerReconstructor w(p);
	w.release("../work"); // never anything outside captures/
	assert_int_equal(stat(p.spool_dir.c_str(), &st), 0);
	w.release(c.scan_name);
	assert_int_not_equal(stat(kept.c_str(), &st), 0);

	// keep_captures: release keeps it; a set outside the scratch is never moved.
	p.keep_captures = true;
	c.source_dir = outside;
	expect_failure(p, c, -ECHILD, "crashed (signal 9", kept);
	assert_int_equal(stat((outside + "/calibration.yaml").c_str(), &st), 0);
	WorkerReconstructor keeping(p);
	keeping.release(c.scan_name);
	assert_int_equal(stat((kept + "/calibration.yaml").c_str(), &st), 0);
}

// Frames from real cameras are written as a whole set (with the booth's calibration) first.
static void test_frames_are_written_as_a_set(void **)
{
	TmpDir d;
	WorkerParams p;
	p.spool_dir = d.path + "/spool";
	mkdir(p.spool_dir.c_str(), 0750);
	p.memory_mb = 0;
	p.calibration_file = d.path + "/calibration.yaml";
	assert_true(facescan::write_calibration(p.calibration_file, small_calibration()).ok());
	p.program = script(d, "crash", "kill -SEGV $$");
	DriverCameras cams("fake", "", 2, 8000, 1000);
	assert_true(cams.open().ok());
	assert_true(cams.prepare().ok());
	TriggerReport r;
	r.sequence = 1;
	Capture c;
	assert_true(cams.collect(r, 100, &c).ok());
	c.scan_name = "20260101T000000Z_def";
	expect_failure(p, c, -ECHILD, "crashed", p.spool_dir + "/captures/" + c.scan_name);
	// without a calibration the frames are kept all the same
	p.calibration_file = d.path + "/missing.yaml";
	c.scan_name = "20260101T000000Z_ghi";
	WorkerReconstructor w(p);
	ReconOutput out;
	facescan::Status s = w.run(c, &out);
	assert_int_equal(s.code(), -ENOENT);
	assert_non_null(std::strstr(s.message().c_str(), "frames kept in"));
	struct stat st;
	assert_int_equal(stat((p.spool_dir + "/captures/" + c.scan_name + "/cam1.png").c_str(), &st), 0);
}

// The daemon lives through a worker crash: the scan fails with the reason, the booth serves on.
static void test_daemon_survives_worker_crash(void **)
{
	TmpDir d;
	mkdir((d.path + "/share").c_str(), 0755);
	Config cfg;
	cfg.share_dir = d.path + "/share";
	cfg.spool_dir = d.path + "/spool";
	cfg.socket_path = d.path + "/sock";
	cfg.serial_device = "fake";
	cfg.camera_backend = "fake";
	cfg.recon_backend = "fake"; // replaced by the worker below
	cfg.min_free_mb = 0;
	cfg.mcu_timeout_ms = 200;
	cfg.capture_timeout_ms = 200;
	WorkerParams p;
	p.spool_dir = cfg.spool_dir;
	p.memory_mb = 0;
	p.calibration_file = d.path + "/calibration.yaml";
	facescan::Calibration cal = small_calibration();
	cal.cameras.push_back(cal.cameras[0]);
	cal.cameras.push_back(cal.cameras[1]);
	assert_true(facescan::write_calibration(p.calibration_file, cal).ok());
	p.program = script(d, "crash", "kill -SEGV $$");
	Backends b;
	assert_true(make_backends(cfg, BoothFactory(), &b).ok());
	b.recon = std::make_unique<WorkerReconstructor>(p);
	Daemon daemon(cfg, std::move(b));
	assert_true(daemon.start().ok());
	std::thread loop([&] { daemon.run(); });
	json last;
	for (int scan = 0; scan < 2; scan++) {
		facescan::Status s = control_request(cfg.socket_path, {{"cmd", "scan"}, {"patient", "W-1"}, {"wait", true}},
						     [&](const json &j) {
							     last = j;
							     return j.value("event", "") != "done" && j.value("ok", true);
						     },
						     10000);
		assert_true(s.ok());
		assert_string_equal(last["scan"]["state"].get<std::string>().c_str(), "failed");
		assert_string_equal(last["scan"]["failed_stage"].get<std::string>().c_str(), "reconstructing");
		const std::string err = last["scan"]["error"];
		assert_non_null(std::strstr(err.c_str(), "crashed (signal 11"));
		assert_non_null(std::strstr(err.c_str(), ("capture kept in " + cfg.spool_dir + "/captures/").c_str()));
		for (int i = 0; i < 300 && daemon.state() != State::idle; i++)
			std::this_thread::sleep_for(std::chrono::milliseconds(10));
		assert_int_equal(static_cast<int>(daemon.state()), static_cast<int>(State::idle));
	}
	daemon.request_stop();
	loop.join();
}

// The real worker on a simulated set: the daemon gets the mesh, the stage times and the accuracy.
static void test_real_worker_on_a_simulated_set(void **)
{
	const char *bin = std::getenv("FACESCAN_BIN");
	if (!bin) {
		std::printf("  FACESCAN_BIN not set: the real worker is not run\n");
		return;
	}
	TmpDir d;
	// Half resolution: this checks the worker's plumbing, tests/recon the reconstruction.
	facescan::sim::Rig rig = facescan::sim::default_rig();
	assert_true(facescan::sim::scale_rig(0.5, &rig).ok());
	facescan::sim::Scene scene;
	assert_true(facescan::sim::scene_by_name("default", &scene).ok());
	facescan::Pattern pattern;
	assert_true(facescan::default_pattern(facescan::SlideSpec(), &pattern).ok());
	facescan::CaptureSet set;
	facescan::sim::SimTruth truth;
	facescan::sim::SimOptions options;
	options.texture_frames = false;
	assert_true(facescan::sim::simulate(rig, scene, pattern, 1, &set, &truth, options).ok());
	const std::string dir = d.path + "/sim";
	assert_true(facescan::sim::write_simulated_set(dir, set, truth).ok());
	WorkerParams p;
	p.program = std::string(bin) + "/facescan";
	p.spool_dir = d.path + "/spool";
	mkdir(p.spool_dir.c_str(), 0750);
	p.memory_mb = 0; // the sanitizer build reserves terabytes of address space
	Capture c;
	c.source_dir = dir;
	c.scan_name = "20260101T000000Z_sim";
	WorkerReconstructor w(p);
	ReconOutput out;
	facescan::Status s = w.run(c, &out);
	if (!s.ok())
		fail_msg("%s", s.message().c_str());
	facescan::recon::Mesh mesh;
	assert_true(facescan::mesh_io::decode_draco(out.drc.data(), out.drc.size(), &mesh).ok());
	assert_int_equal(out.vertices, static_cast<long>(mesh.positions.size()));
	assert_true(out.vertices > 1000);
	assert_true(out.png.size() > 8 && out.png.compare(1, 3, "PNG") == 0);
	const double completeness = out.quality["accuracy"]["completeness"].get<double>();
	std::printf("  real worker: %ld vertices, completeness %.1f %%\n", out.vertices, 100 * completeness);
	assert_true(completeness >= 0.5);
	bool detect = false, worker = false;
	for (const auto &st : out.stage_ms) {
		detect = detect || st.first == "detect";
		worker = worker || st.first == "worker";
	}
	assert_true(detect && worker);
	assert_true(out.quality["warnings"].is_array() && out.quality["warnings"].empty());
	struct stat st;
	assert_int_not_equal(stat((p.spool_dir + "/captures/" + c.scan_name).c_str(), &st), 0);

	// Another valid pattern id than the one projected: warned (few squares decode), and every
	// camera matched in no pair is named.
	{
		std::ifstream in(dir + "/capture.json");
		std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
		const size_t at = text.find(pattern.id);
		assert_true(at != std::string::npos);
		text.replace(at, pattern.id.size(), "fs-l3-14x19-s70");
		std::ofstream(dir + "/capture.json") << text;
	}
	ReconOutput wrong;
	s = w.run(c, &wrong);
	if (!s.ok()) {
		// as refused as it may be: the reason names the cause, the set is kept
		std::printf("  wrong pattern refused: %s\n", s.message().c_str());
		assert_non_null(std::strstr(s.message().c_str(), "capture kept in"));
		return;
	}
	const json &warnings = wrong.quality["warnings"];
	std::printf("  wrong pattern: %s\n", warnings.dump().c_str());
	assert_true(warnings.is_array() && !warnings.empty());
	assert_non_null(std::strstr(warnings[0].get<std::string>().c_str(), "decoded with pattern fs-l3-14x19-s70"));
	for (const json &cam : wrong.quality["cameras"]) {
		int matched = 0;
		for (const json &pair : wrong.quality["pairs"])
			if (pair["cameras"][0] == cam["camera"] || pair["cameras"][1] == cam["camera"])
				matched += pair["matches"].get<int>();
		const std::string named = "camera " + std::to_string(cam["camera"].get<int>()) + " has no seeds";
		bool warned = false;
		for (const json &wtext : warnings)
			warned = warned || wtext.get<std::string>().find(named) != std::string::npos;
		assert_true(warned == (matched == 0));
	}
}

int main()
{
	set_log_sink([](int, const std::string &) {});
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_child_limits),
		cmocka_unit_test(test_worker_failures_keep_the_capture),
		cmocka_unit_test(test_scratch_set_becomes_the_scans),
		cmocka_unit_test(test_frames_are_written_as_a_set),
		cmocka_unit_test(test_daemon_survives_worker_crash),
		cmocka_unit_test(test_real_worker_on_a_simulated_set),
	};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
