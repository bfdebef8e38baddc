// Where finished scans go: first into the local spool (a commit point that survives a crash),
// then onto the share with atomic renames (drivers/storage's atomic write). A scan lives in <spool>/queue/<base>/ as its files
// plus manifest.json, written last: an entry without a manifest was interrupted while being
// written and is reported failed at the next start. Delivery copies every file to
// <share>/<patient>/<file> (temp file → fsync → rename → fsync dir; metadata .json last), then
// removes the entry. Names are fixed per scan, so a delivery repeated after a crash replaces
// the same files: nothing is duplicated. The share root is never created (an absent share is an
// unmounted share); the patient folder is.
#pragma once

#include "common/status.hpp"

#include <string>
#include <utility>
#include <vector>

namespace facescan::daemon {

struct SpoolFile {
	std::string name;     // final file name, e.g. 20261124T214510Z_3fa2c19e0b4d.drc
	std::string contents;
};

struct Delivered {
	std::string base;     // <UTC time>_<scan-id>
	std::string scan_id;
	std::string patient_id;
	std::vector<std::string> paths;  // where the files landed
};

/// Writes `contents` to dir/name atomically (mode 0640) with drivers/storage's
/// fscan_write_file_atomic(). A crash leaves the old file or the new one, plus at most a hidden
/// ".fscan-tmp.<pid>..." temp file that the next write into that directory removes.
Status write_file_atomic(const std::string &dir, const std::string &name, const std::string &contents);

class Spool {
public:
	/// share_marker: a file that must exist at the share's root for it to count as mounted
	/// (drivers/storage's guard); "" checks only that the directory exists.
	Spool(std::string spool_dir, std::string share_dir, long min_free_mb, std::string share_marker = "");

	/// Creates <spool>/queue and <spool>/state when missing.
	Status init();
	/// Queues one scan. `delay_ms` pauses between files (fault tests).
	Status put(const std::string &base, const std::string &scan_id, const std::string &patient_id,
		   const std::vector<SpoolFile> &files, int delay_ms);
	/// Removes entries that have no manifest (interrupted while spooling); returns their scan ids.
	Status recover(std::vector<std::string> *ret_failed_scan_ids);
	/// Delivers queued entries oldest first and stops at the first failure, which is returned
	/// (-ENOENT: share missing, -ENOSPC: share full, -EIO...). Delivered entries go to ret.
	Status deliver(std::vector<Delivered> *ret_delivered, int delay_ms);
	/// Whether a scan can be spooled now: a probe file written (atomically) and removed in the
	/// queue. -EROFS / -EACCES / -ENOSPC / -ENOTDIR ... with a message naming the spool.
	Status writable() const;
	/// Entries waiting in the queue.
	size_t pending() const;
	/// Whether scan `scan_id` waits in the queue, complete (its manifest written).
	bool queued(const std::string &scan_id) const;
	/// Whether the share can take `bytes` more now.
	Status share_ready(unsigned long long bytes) const;

	const std::string &state_dir() const
	{
		return state_dir_;
	}

private:
	std::string queue_dir_, state_dir_, share_dir_, share_marker_;
	long min_free_mb_;
	std::vector<std::string> entries() const;
};

} // namespace facescan::daemon
