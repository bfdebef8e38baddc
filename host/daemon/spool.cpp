#include "daemon/spool.hpp"

#include "facescan/storage.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <dirent.h>
#include <fcntl.h>
#include <fstream>
#include <sstream>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <thread>
#include <unistd.h>

namespace facescan::daemon {

namespace {

Status errno_status(int err, const std::string &what)
{
	return Status::error(err, what + ": " + std::strerror(err));
}

Status fsync_dir(const std::string &dir)
{
	int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0)
		return errno_status(errno, dir);
	int r = fsync(fd);
	int err = errno;
	::close(fd);
	if (r < 0)
		return errno_status(err, "fsync " + dir);
	return Status();
}

Status read_file(const std::string &path, std::string *ret)
{
	std::ifstream f(path, std::ios::binary);
	if (!f)
		return Status::error(ENOENT, path + ": cannot read");
	std::ostringstream ss;
	ss << f.rdbuf();
	*ret = ss.str();
	return Status();
}

std::vector<std::string> list_dir(const std::string &dir)
{
	std::vector<std::string> names;
	DIR *d = opendir(dir.c_str());
	if (!d)
		return names;
	while (struct dirent *e = readdir(d)) {
		std::string n = e->d_name;
		if (n != "." && n != "..")
			names.push_back(n);
	}
	closedir(d);
	std::sort(names.begin(), names.end());
	return names;
}

Status remove_tree(const std::string &dir)
{
	for (const std::string &n : list_dir(dir))
		if (unlink((dir + "/" + n).c_str()) < 0 && errno != ENOENT)
			return errno_status(errno, dir + "/" + n);
	if (rmdir(dir.c_str()) < 0 && errno != ENOENT)
		return errno_status(errno, dir);
	return Status();
}

Status mkdir_if_missing(const std::string &dir, mode_t mode)
{
	if (mkdir(dir.c_str(), mode) < 0 && errno != EEXIST)
		return errno_status(errno, "mkdir " + dir);
	struct stat st;
	if (stat(dir.c_str(), &st) < 0 || !S_ISDIR(st.st_mode))
		return Status::error(ENOTDIR, dir + ": not a directory");
	return Status();
}

// 0 B, 812 KiB, 3.4 MiB, 2.0 GiB: "0 MiB free, needs 0 MiB" said nothing.
std::string human_bytes(unsigned long long n)
{
	char buf[32];
	if (n < 1024)
		std::snprintf(buf, sizeof buf, "%llu B", n);
	else if (n < (1ULL << 20))
		std::snprintf(buf, sizeof buf, "%.0f KiB", double(n) / 1024);
	else if (n < (1ULL << 30))
		std::snprintf(buf, sizeof buf, "%.1f MiB", double(n) / (1 << 20));
	else
		std::snprintf(buf, sizeof buf, "%.1f GiB", double(n) / (1 << 30));
	return buf;
}

void pause_ms(int ms)
{
	if (ms > 0)
		std::this_thread::sleep_for(std::chrono::milliseconds(ms));
}

} // namespace

Status write_file_atomic(const std::string &dir, const std::string &name, const std::string &contents)
{
	// Temp files of writers that died (kill -9 mid-write) go first: ".fscan-tmp.<pid>.<n>.<name>"
	// is drivers/storage's naming; a live pid is another writer at work and is left alone.
	const std::string prefix = ".fscan-tmp.";
	for (const std::string &n : list_dir(dir)) {
		if (n.compare(0, prefix.size(), prefix) != 0)
			continue;
		long pid = std::strtol(n.c_str() + prefix.size(), nullptr, 10);
		if (pid > 0 && kill(static_cast<pid_t>(pid), 0) < 0 && errno == ESRCH)
			unlink((dir + "/" + n).c_str());
	}
	int rc = fscan_write_file_atomic(dir.c_str(), name.c_str(), contents.data(), contents.size(), 0640);
	if (rc < 0)
		return errno_status(-rc, "write " + dir + "/" + name);
	return Status();
}

Spool::Spool(std::string spool_dir, std::string share_dir, long min_free_mb, std::string share_marker)
	: queue_dir_(spool_dir + "/queue"), state_dir_(spool_dir + "/state"), share_dir_(std::move(share_dir)),
	  share_marker_(std::move(share_marker)), min_free_mb_(min_free_mb)
{
}

Status Spool::init()
{
	std::string root = queue_dir_.substr(0, queue_dir_.size() - 6);
	Status s = mkdir_if_missing(root, 0750);
	if (s.ok())
		s = mkdir_if_missing(queue_dir_, 0750);
	if (s.ok())
		s = mkdir_if_missing(state_dir_, 0750);
	return s;
}

std::vector<std::string> Spool::entries() const
{
	std::vector<std::string> out;
	for (const std::string &n : list_dir(queue_dir_))
		if (n[0] != '.')
			out.push_back(n);
	return out;
}

size_t Spool::pending() const
{
	size_t n = 0;
	for (const std::string &e : entries())
		if (access((queue_dir_ + "/" + e + "/manifest.json").c_str(), F_OK) == 0)
			n++;
	return n;
}

Status Spool::writable() const
{
	int rc = fscan_write_file_atomic(queue_dir_.c_str(), ".probe", "", 0, 0600);
	if (rc < 0)
		return Status::error(-rc, "spool " + queue_dir_ + " is not writable: " + std::strerror(-rc));
	unlink((queue_dir_ + "/.probe").c_str());
	return Status();
}

bool Spool::queued(const std::string &scan_id) const
{
	const std::string tail = "_" + scan_id;
	for (const std::string &e : entries())
		if (e.size() > tail.size() && e.compare(e.size() - tail.size(), tail.size(), tail) == 0 &&
		    access((queue_dir_ + "/" + e + "/manifest.json").c_str(), F_OK) == 0)
			return true;
	return false;
}

Status Spool::put(const std::string &base, const std::string &scan_id, const std::string &patient_id,
		  const std::vector<SpoolFile> &files, int delay_ms)
{
	const std::string dir = queue_dir_ + "/" + base;
	Status s = mkdir_if_missing(dir, 0750);
	if (!s.ok())
		return s;
	nlohmann::json names = nlohmann::json::array();
	for (const SpoolFile &f : files) {
		s = write_file_atomic(dir, f.name, f.contents);
		if (!s.ok())
			return s;
		names.push_back(f.name);
		pause_ms(delay_ms);
	}
	nlohmann::json manifest = {{"scan_id", scan_id}, {"patient_id", patient_id}, {"files", names}};
	s = write_file_atomic(dir, "manifest.json", manifest.dump(1) + "\n");
	if (!s.ok())
		return s;
	return fsync_dir(queue_dir_);
}

Status Spool::recover(std::vector<std::string> *ret_failed_scan_ids)
{
	ret_failed_scan_ids->clear();
	for (const std::string &n : list_dir(queue_dir_))
		if (n.compare(0, 6, ".done-") == 0) {
			Status s = remove_tree(queue_dir_ + "/" + n);
			if (!s.ok())
				return s;
		}
	for (const std::string &e : entries()) {
		const std::string dir = queue_dir_ + "/" + e;
		if (access((dir + "/manifest.json").c_str(), F_OK) == 0)
			continue;
		// <UTC time>_<scan-id>: the scan id follows the last '_'
		size_t us = e.rfind('_');
		ret_failed_scan_ids->push_back(us == std::string::npos ? e : e.substr(us + 1));
		Status s = remove_tree(dir);
		if (!s.ok())
			return s;
	}
	return Status();
}

Status Spool::share_ready(unsigned long long bytes) const
{
	// The storage driver's guard: an unmounted share's mount point is an empty local directory,
	// and a scan written there would never reach the clinic.
	int rc = fscan_storage_share_present(share_dir_.c_str(), share_marker_.c_str());
	if (rc == -ENOENT && !share_marker_.empty() && access(share_dir_.c_str(), F_OK) == 0)
		return Status::error(ENOENT, "share " + share_dir_ + " is not mounted (no " + share_marker_ +
						     " at its root)");
	if (rc < 0)
		return Status::error(ENOENT, "share " + share_dir_ + " is missing");
	struct statvfs vfs;
	if (statvfs(share_dir_.c_str(), &vfs) < 0)
		return errno_status(errno, "statvfs " + share_dir_);
	unsigned long long avail = static_cast<unsigned long long>(vfs.f_bavail) * vfs.f_frsize;
	unsigned long long need = bytes + static_cast<unsigned long long>(min_free_mb_) * 1024 * 1024;
	if (avail < need)
		return Status::error(ENOSPC, "share " + share_dir_ + " has " + human_bytes(avail) + " free, needs " +
						     human_bytes(need) + " (the scan's " + human_bytes(bytes) +
						     " + min_free_mb)");
	if (access(share_dir_.c_str(), W_OK) < 0)
		return errno_status(errno, "share " + share_dir_);
	return Status();
}

Status Spool::deliver(std::vector<Delivered> *ret_delivered, int delay_ms)
{
	ret_delivered->clear();
	for (const std::string &e : entries()) {
		const std::string dir = queue_dir_ + "/" + e;
		std::string text;
		if (!read_file(dir + "/manifest.json", &text).ok())
			continue; // being written right now, or left for recover()
		nlohmann::json m = nlohmann::json::parse(text, nullptr, false);
		if (m.is_discarded() || !m.contains("patient_id") || !m.contains("files") ||
		    !m["files"].is_array())
			return Status::error(EPROTO, dir + "/manifest.json: malformed");
		Delivered d;
		d.base = e;
		d.scan_id = m.value("scan_id", "");
		d.patient_id = m["patient_id"].get<std::string>();
		std::vector<std::pair<std::string, std::string>> files;
		unsigned long long bytes = 0;
		for (const auto &n : m["files"]) {
			std::string name = n.get<std::string>(), contents;
			Status s = read_file(dir + "/" + name, &contents);
			if (!s.ok())
				return s;
			bytes += contents.size();
			files.emplace_back(name, std::move(contents));
		}
		Status s = share_ready(bytes);
		if (!s.ok())
			return s;
		const std::string target = share_dir_ + "/" + d.patient_id;
		s = mkdir_if_missing(target, 0750);
		if (!s.ok())
			return s;
		// Metadata last: whoever sees the .json sees the mesh and texture already complete.
		std::stable_partition(files.begin(), files.end(), [](const auto &f) {
			return f.first.size() < 5 || f.first.compare(f.first.size() - 5, 5, ".json") != 0;
		});
		for (const auto &f : files) {
			s = write_file_atomic(target, f.first, f.second);
			if (!s.ok())
				return s;
			d.paths.push_back(target + "/" + f.first);
			pause_ms(delay_ms);
		}
		s = fsync_dir(share_dir_);
		if (!s.ok())
			return s;
		// Out of the queue in one rename; a crash before the removal leaves a hidden .done-
		// folder that recover() clears, never a half entry that would look failed.
		const std::string done = queue_dir_ + "/.done-" + e;
		if (rename(dir.c_str(), done.c_str()) < 0)
			return errno_status(errno, "rename " + dir);
		s = fsync_dir(queue_dir_);
		if (s.ok())
			s = remove_tree(done);
		if (!s.ok())
			return s;
		ret_delivered->push_back(std::move(d));
	}
	return Status();
}

} // namespace facescan::daemon
