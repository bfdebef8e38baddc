#include "daemon/worker_recon.hpp"

#include "capture/capture_set.hpp"
#include "daemon/pipeline_recon.hpp"
#include "mesh_io/mesh_io.hpp"
#include "pattern/pattern.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <dirent.h>
#include <fcntl.h>
#include <poll.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace facescan::daemon {

namespace {

using Clock = std::chrono::steady_clock;
constexpr size_t kStderrKeep = 16 * 1024;

Status errno_status(int err, const std::string &what)
{
	return Status::error(err, what + ": " + std::strerror(err));
}

std::vector<std::string> list_dir(const std::string &dir)
{
	std::vector<std::string> names;
	if (DIR *d = opendir(dir.c_str())) {
		while (dirent *e = readdir(d))
			if (std::strcmp(e->d_name, ".") != 0 && std::strcmp(e->d_name, "..") != 0)
				names.push_back(e->d_name);
		closedir(d);
	}
	return names;
}

// Our own scratch directory: flat, so one level of unlink is all it takes.
void remove_flat_dir(const std::string &dir)
{
	for (const std::string &n : list_dir(dir))
		unlink((dir + "/" + n).c_str());
	rmdir(dir.c_str());
}

Status mkdir_p1(const std::string &dir)
{
	if (mkdir(dir.c_str(), 0750) < 0 && errno != EEXIST)
		return errno_status(errno, "mkdir " + dir);
	return Status();
}

Status read_bounded(const std::string &path, size_t max_bytes, std::string *ret)
{
	return read_regular_file(path, max_bytes, ret);
}

// The capture files of a set (docs/capture-format.md), copied so a failed scan's set outlives
// the simulated backend's scratch directory, which the next scan overwrites.
Status copy_capture_set(const std::string &from, const std::string &to)
{
	Status s = mkdir_p1(to);
	for (const std::string &n : list_dir(from)) {
		if (!s.ok())
			break;
		struct stat st;
		if (stat((from + "/" + n).c_str(), &st) < 0 || !S_ISREG(st.st_mode) || n[0] == '.')
			continue;
		std::string bytes;
		s = read_bounded(from + "/" + n, size_t(512) << 20, &bytes);
		if (s.ok())
			s = write_file_atomic(to + "/" + n, bytes.data(), bytes.size());
	}
	return s;
}

// The last non-empty line, without the program's "facescan recon: " prefix.
std::string last_line(const std::string &text)
{
	size_t end = text.find_last_not_of("\n\r ");
	if (end == std::string::npos)
		return "";
	size_t start = text.find_last_of('\n', end);
	std::string line = text.substr(start == std::string::npos ? 0 : start + 1, end - (start == std::string::npos ? 0 : start + 1) + 1);
	const std::string prefix = "facescan recon: ";
	if (line.compare(0, prefix.size(), prefix) == 0)
		line.erase(0, prefix.size());
	return line;
}

} // namespace

Status run_with_limits(const std::vector<std::string> &argv, int timeout_ms, int memory_mb, ChildResult *ret)
{
	// Everything the child needs is made before fork(): in a threaded parent, the child may
	// only make async-signal-safe calls until it execs.
	std::vector<char *> args;
	for (const std::string &a : argv)
		args.push_back(const_cast<char *>(a.c_str()));
	args.push_back(nullptr);
	int err_pipe[2];
	if (pipe2(err_pipe, O_CLOEXEC) < 0)
		return errno_status(errno, "pipe");
	int devnull = ::open("/dev/null", O_RDWR | O_CLOEXEC);
	if (devnull < 0) {
		int e = errno;
		::close(err_pipe[0]);
		::close(err_pipe[1]);
		return errno_status(e, "/dev/null");
	}
	struct rlimit as = {};
	as.rlim_cur = as.rlim_max = static_cast<rlim_t>(memory_mb) << 20;
	const pid_t parent = getpid();
	pid_t pid = fork();
	if (pid < 0) {
		int e = errno;
		::close(err_pipe[0]);
		::close(err_pipe[1]);
		::close(devnull);
		return errno_status(e, "fork");
	}
	if (pid == 0) {
		// The worker must not outlive a daemon killed with -9.
		prctl(PR_SET_PDEATHSIG, SIGKILL);
		if (getppid() != parent)
			_exit(127);
		dup2(devnull, STDIN_FILENO);
		dup2(devnull, STDOUT_FILENO);
		dup2(err_pipe[1], STDERR_FILENO);
		if (memory_mb > 0)
			setrlimit(RLIMIT_AS, &as);
		// The daemon ignores SIGPIPE; the worker starts with the default dispositions.
		signal(SIGPIPE, SIG_DFL);
		execv(args[0], args.data());
		const char msg[] = "cannot execute the reconstruction worker\n";
		if (write(STDERR_FILENO, msg, sizeof msg - 1) < 0) {
			// nothing left to tell
		}
		_exit(127);
	}
	::close(err_pipe[1]);
	::close(devnull);
	ChildResult r;
	const auto deadline = Clock::now() + std::chrono::milliseconds(timeout_ms);
	bool eof = false, reaped = false;
	int status = 0;
	while (!reaped) {
		const int left = static_cast<int>(
			std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count());
		if (left <= 0) {
			r.timed_out = true;
			break;
		}
		if (eof) {
			// stderr closed: it has exited, or is about to (or closed stderr and runs on).
			pid_t w = waitpid(pid, &status, WNOHANG);
			if (w == pid)
				reaped = true;
			else
				poll(nullptr, 0, std::min(left, 10));
			continue;
		}
		pollfd p = {err_pipe[0], POLLIN, 0};
		int n = poll(&p, 1, left);
		if (n <= 0)
			continue; // EINTR or the deadline: the loop decides
		char buf[4096];
		ssize_t got = read(err_pipe[0], buf, sizeof buf);
		if (got > 0) {
			r.stderr_tail.append(buf, static_cast<size_t>(got));
			if (r.stderr_tail.size() > kStderrKeep)
				r.stderr_tail.erase(0, r.stderr_tail.size() - kStderrKeep);
		} else if (got == 0 || errno != EINTR) {
			eof = true;
		}
	}
	::close(err_pipe[0]);
	if (!reaped) {
		// Past its deadline: killed and reaped, never left running or as a zombie.
		kill(pid, SIGKILL);
		while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
		}
	}
	if (WIFEXITED(status))
		r.exit_code = WEXITSTATUS(status);
	else if (WIFSIGNALED(status))
		r.signal = WTERMSIG(status);
	*ret = std::move(r);
	return Status();
}

Status WorkerReconstructor::run(const Capture &capture, ReconOutput *ret_output)
{
	const std::string name = capture.scan_name.empty() ? "scan" : capture.scan_name;
	const std::string kept = p_.spool_dir + "/captures/" + name;
	Status s = mkdir_p1(p_.spool_dir + "/captures");
	if (s.ok())
		s = mkdir_p1(p_.spool_dir + "/work");
	if (!s.ok())
		return s;

	// The input: the set the cameras left on disk, or the frames written as one.
	std::string input = capture.source_dir;
	bool wrote_set = false;
	const std::string scratch = p_.spool_dir + "/work/";
	if (!input.empty() && input.compare(0, scratch.size(), scratch) == 0) {
		// The cameras' scratch set (the simulated booth's) is overwritten by the next scan:
		// it becomes this scan's before the worker runs, so a failure or a kill keeps it.
		if (rename(input.c_str(), kept.c_str()) < 0)
			return errno_status(errno, "rename " + input + " to " + kept);
		input = kept;
		wrote_set = true;
	} else if (input.empty()) {
		CaptureSet set;
		s = read_calibration(p_.calibration_file, &set.calibration);
		for (const Frame &f : capture.frames) {
			auto &v = f.texture ? set.textures : set.frames;
			if (v.size() <= static_cast<size_t>(f.camera))
				v.resize(static_cast<size_t>(f.camera) + 1);
			v[static_cast<size_t>(f.camera)] = f.image;
		}
		Pattern pattern;
		if (s.ok())
			s = p_.pattern_id.empty() ? default_pattern(SlideSpec(), &pattern)
						  : pattern_from_id(p_.pattern_id, SlideSpec(), &pattern);
		set.meta.scan_id = name.substr(name.rfind('_') + 1);
		set.meta.pattern_id = pattern.id;
		if (s.ok())
			s = write_capture_set(kept, set);
		if (!s.ok()) {
			// Keep the frames at least; without a calibration they are not yet a set.
			mkdir_p1(kept);
			for (const Frame &f : capture.frames)
				write_image_atomic(kept + "/cam" + std::to_string(f.camera) + (f.texture ? "_texture" : "") + ".png",
						   f.image);
			return Status::error(s.code(), s.message() + "; frames kept in " + kept);
		}
		input = kept;
		wrote_set = true;
	}
	auto keep_for_retry = [&](const Status &why) {
		if (!wrote_set) {
			Status c = copy_capture_set(input, kept);
			if (!c.ok())
				return Status::error(why.code(), why.message() + "; could not keep the capture set: " + c.message());
		}
		return Status::error(why.code(), why.message() + "; capture kept in " + kept +
							 " for an offline retry (facescan recon " + kept + " -o OUT.drc)");
	};

	char tmpl_buf[4096];
	std::snprintf(tmpl_buf, sizeof tmpl_buf, "%s/work/recon-XXXXXX", p_.spool_dir.c_str());
	if (!mkdtemp(tmpl_buf))
		return keep_for_retry(errno_status(errno, "mkdtemp " + p_.spool_dir + "/work"));
	const std::string work = tmpl_buf;
	const std::string drc_path = work + "/mesh.drc", png_path = work + "/mesh.png", report_path = work + "/report.json";
	ChildResult child;
	const auto t0 = Clock::now();
	s = run_with_limits({p_.program, "recon", input, "-o", drc_path, "--report", report_path}, p_.timeout_ms,
			    p_.memory_mb, &child);
	const double worker_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
	ReconOutput out;
	std::string report_text;
	if (s.ok()) {
		const std::string said = last_line(child.stderr_tail);
		const bool no_memory = child.stderr_tail.find("bad_alloc") != std::string::npos ||
				       child.stderr_tail.find("Insufficient memory") != std::string::npos ||
				       child.stderr_tail.find("Failed to allocate") != std::string::npos ||
				       child.stderr_tail.find("failed to map segment") != std::string::npos ||
				       child.stderr_tail.find("Cannot allocate memory") != std::string::npos;
		if (child.timed_out)
			s = Status::error(ETIMEDOUT, "reconstruction worker killed after " + std::to_string(p_.timeout_ms) +
							     " ms (recon_timeout_ms)");
		else if (no_memory)
			s = Status::error(ENOMEM, "reconstruction worker ran out of memory (recon_memory_mb = " +
							  std::to_string(p_.memory_mb) + ")");
		else if (child.signal)
			s = Status::error(ECHILD, "reconstruction worker crashed (signal " + std::to_string(child.signal) +
							  ", " + strsignal(child.signal) + ")");
		else if (child.exit_code != 0)
			s = Status::error(EIO, said.empty() ? "reconstruction worker failed (exit " +
								       std::to_string(child.exit_code) + ")"
							    : said);
	}
	if (s.ok())
		s = read_bounded(drc_path, size_t(512) << 20, &out.drc);
	if (s.ok())
		s = read_bounded(report_path, size_t(16) << 20, &report_text);
	if (s.ok() && access(png_path.c_str(), F_OK) == 0)
		s = read_bounded(png_path, size_t(512) << 20, &out.png);
	remove_flat_dir(work);
	if (!s.ok())
		return keep_for_retry(s);

	out.quality = nlohmann::json::parse(report_text, nullptr, false);
	if (!out.quality.is_object())
		return keep_for_retry(Status::error(EPROTO, "reconstruction worker: report is not a JSON object"));
	out.vertices = out.quality.value("vertices", 0L);
	out.faces = out.quality.value("triangles", 0L);
	if (out.quality.contains("time_ms") && out.quality["time_ms"].is_object())
		for (auto it = out.quality["time_ms"].begin(); it != out.quality["time_ms"].end(); ++it)
			if (it.key() != "total" && it->is_number())
				out.stage_ms.emplace_back(it.key(), it->get<double>());
	out.stage_ms.emplace_back("worker", worker_ms);
	if (out.png.empty()) {
		// No texture atlas: the first texture (or pattern) frame stands in, as before.
		CaptureSet set;
		if (read_capture_set(input, &set).ok()) {
			const cv::Mat &tex = !set.textures.empty() ? set.textures[0] : set.frames[0];
			std::vector<uchar> png;
			if (cv::imencode(".png", tex, png))
				out.png.assign(png.begin(), png.end());
		}
	}
	// A simulated set is scored against its ground truth, from the mesh as delivered.
	recon::Mesh mesh;
	Calibration cal;
	if (!mesh_io::decode_draco(out.drc.data(), out.drc.size(), &mesh).ok())
		return keep_for_retry(Status::error(EPROTO, "reconstruction worker: its mesh does not decode"));
	// The counts of the file delivered (Draco may drop an unreferenced vertex).
	out.vertices = static_cast<long>(mesh.positions.size());
	out.faces = static_cast<long>(mesh.triangles.size());
	if (read_calibration(input + "/calibration.yaml", &cal).ok())
		add_simulated_accuracy(input, mesh, cal.cameras, &out);
	*ret_output = std::move(out);
	return Status();
}

void WorkerReconstructor::release(const std::string &scan_name)
{
	if (p_.keep_captures || scan_name.empty() || scan_name.find('/') != std::string::npos || scan_name[0] == '.')
		return;
	// Committed to the spool; the daemon's keep_captures decides about raw sets.
	const std::string kept = p_.spool_dir + "/captures/" + scan_name;
	for (const std::string &n : list_dir(kept))
		unlink((kept + "/" + n).c_str());
	rmdir(kept.c_str());
}

} // namespace facescan::daemon
