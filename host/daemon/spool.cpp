#include "daemon/spool.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <sys/stat.h>
#include <unistd.h>

namespace facescan::daemon {

namespace {

Status errno_status(int err, const std::string &what)
{
	return Status::error(err, what + ": " + std::strerror(err));
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

} // namespace

Status write_file_atomic(const std::string &dir, const std::string &name, const std::string &contents)
{
	int rc = fscan_write_file_atomic(dir.c_str(), name.c_str(), contents.data(), contents.size(), 0640);
	if (rc < 0)
		return errno_status(-rc, "write " + dir + "/" + name);
	return Status();
}

Spool::Spool(std::string spool_dir, std::string share_dir, long min_free_mb, std::string share_marker,
	     const fscan_storage_ops *ops)
	: root_(spool_dir), queue_dir_(spool_dir + "/queue"), state_dir_(spool_dir + "/state"),
	  share_dir_(std::move(share_dir)), share_marker_(std::move(share_marker)), min_free_mb_(min_free_mb), ops_(ops)
{
}

Status Spool::init()
{
	Status s = mkdir_if_missing(root_, 0750);
	if (s.ok())
		s = mkdir_if_missing(state_dir_, 0750);
	if (!s.ok())
		return s;
	fscan_storage_config cfg = {};
	cfg.share_dir = share_dir_.c_str();
	cfg.spool_dir = queue_dir_.c_str();
	// min_free_mb = 0 means none for the daemon; the driver reads 0 as its default.
	cfg.min_free_bytes = min_free_mb_ > 0 ? static_cast<uint64_t>(min_free_mb_) << 20 : 1;
	cfg.spool_min_free = 1;
	cfg.file_mode = 0640;
	cfg.share_marker = share_marker_.empty() ? nullptr : share_marker_.c_str();
	fscan_storage *st = nullptr;
	int rc = fscan_storage_create(ops_, &cfg, &st);
	if (rc < 0)
		return errno_status(-rc, "spool " + queue_dir_);
	st_.reset(st);
	return Status();
}

Status Spool::put(const std::string &base, const std::string &scan_id, const std::string &patient_id,
		  const std::vector<SpoolFile> &files)
{
	if (!st_)
		return Status::error(EBADF, "spool " + queue_dir_ + " is not open");
	std::vector<fscan_storage_file> v;
	for (const SpoolFile &f : files)
		v.push_back({f.name.c_str(), f.contents.data(), f.contents.size()});
	int rc = fscan_storage_queue(st_.get(), base.c_str(), scan_id.c_str(), patient_id.c_str(), v.data(), v.size());
	if (rc < 0)
		return errno_status(-rc, "spool " + queue_dir_ + "/" + base);
	return Status();
}

Status Spool::recover(std::vector<std::string> *ret_failed_scan_ids)
{
	ret_failed_scan_ids->clear();
	if (!st_)
		return Status::error(EBADF, "spool " + queue_dir_ + " is not open");
	int rc = fscan_storage_recover(
		st_.get(),
		[](const char *id, void *ud) { static_cast<std::vector<std::string> *>(ud)->push_back(id); },
		ret_failed_scan_ids);
	if (rc < 0)
		return errno_status(-rc, "recover " + queue_dir_);
	return Status();
}

Status Spool::share_error(int rc) const
{
	if (rc == -ENOENT && !share_marker_.empty() && access(share_dir_.c_str(), F_OK) == 0)
		return Status::error(ENOENT, "share " + share_dir_ + " is not mounted (no " + share_marker_ +
						     " at its root)");
	if (rc == -ENOENT)
		return Status::error(ENOENT, "share " + share_dir_ + " is missing");
	if (rc == -ENOSPC) {
		uint64_t avail = 0;
		fscan_storage_share_free(st_.get(), &avail);
		unsigned long long need = static_cast<unsigned long long>(min_free_mb_) << 20;
		return Status::error(ENOSPC, "share " + share_dir_ + " has " + human_bytes(avail) +
						     " free, needs the scan + min_free_mb (" + human_bytes(need) + ")");
	}
	return errno_status(-rc, "deliver to share " + share_dir_);
}

Status Spool::deliver(std::vector<Delivered> *ret_delivered, const std::atomic<bool> *stop)
{
	ret_delivered->clear();
	if (!st_)
		return Status::error(EBADF, "spool " + queue_dir_ + " is not open");
	struct Paths {
		const std::string *share;
		std::vector<std::string> v;
	} paths{&share_dir_, {}};
	while (!stop || !*stop) {
		fscan_storage_delivery d = {};
		paths.v.clear();
		int rc = fscan_storage_deliver_next(
			st_.get(), &d,
			[](const char *rel, void *ud) {
				Paths *p = static_cast<Paths *>(ud);
				p->v.push_back(*p->share + "/" + rel);
			},
			&paths);
		if (rc == 0)
			return Status();
		if (rc < 0)
			return share_error(rc);
		ret_delivered->push_back({d.base, d.scan_id, d.dir, std::move(paths.v)});
	}
	return Status();
}

Status Spool::writable() const
{
	int rc = st_ ? fscan_storage_writable(st_.get()) : -EBADF;
	if (rc < 0)
		return Status::error(-rc, "spool " + queue_dir_ + " is not writable: " + std::strerror(-rc));
	return Status();
}

size_t Spool::pending() const
{
	int n = st_ ? fscan_storage_scans(st_.get()) : 0;
	return n > 0 ? static_cast<size_t>(n) : 0;
}

bool Spool::queued(const std::string &scan_id) const
{
	return st_ && fscan_storage_queued(st_.get(), scan_id.c_str()) == 1;
}

} // namespace facescan::daemon
