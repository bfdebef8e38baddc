// Where finished scans go: the storage driver's spool (drivers/include/facescan/storage.h, scan
// entries), first locally (a commit point that survives a crash), then onto the share. This is
// a C++ face over the driver handle and nothing more: the entry layout, the manifest, crash
// recovery, the atomic writes (metadata .json last), the free-space check and the share-mounted
// guard are the driver's. The spool is <spool_dir>/queue (the driver's spool directory) beside
// the daemon's <spool_dir>/state.
#pragma once

#include "common/status.hpp"
#include "facescan/storage.h"

#include <atomic>
#include <memory>
#include <string>
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

/// fscan_write_file_atomic() with a Status: dir/name (mode 0640) holds the old bytes or the
/// new ones, never a mix.
Status write_file_atomic(const std::string &dir, const std::string &name, const std::string &contents);

class Spool {
public:
	/// share_marker: a file that must exist at the share's root for it to count as mounted
	/// (the driver's guard); "" checks only that the directory exists. `ops`: the driver's
	/// backend (posix by default; tests may pass the fake).
	Spool(std::string spool_dir, std::string share_dir, long min_free_mb, std::string share_marker = "",
	      const fscan_storage_ops *ops = &fscan_storage_posix_ops);

	/// Creates <spool>, <spool>/state and opens the driver on <spool>/queue.
	Status init();
	/// fscan_storage_queue(): the scan's files, then its manifest.
	Status put(const std::string &base, const std::string &scan_id, const std::string &patient_id,
		   const std::vector<SpoolFile> &files);
	/// fscan_storage_recover(): the scan ids of entries interrupted while spooled.
	Status recover(std::vector<std::string> *ret_failed_scan_ids);
	/// fscan_storage_deliver_next() until the queue is empty or the share fails, which is
	/// returned (-ENOENT: share missing or not mounted, -ENOSPC: share full, -EIO...), or until
	/// *stop (set from another thread) is seen between two scans.
	Status deliver(std::vector<Delivered> *ret_delivered, const std::atomic<bool> *stop = nullptr);
	/// fscan_storage_writable(), with a message naming the spool.
	Status writable() const;
	/// Complete entries waiting.
	size_t pending() const;
	/// Whether scan `scan_id` waits in the queue, complete.
	bool queued(const std::string &scan_id) const;

	const std::string &state_dir() const
	{
		return state_dir_;
	}
	/// The driver handle (fake back doors in tests); null before init().
	fscan_storage *handle() const
	{
		return st_.get();
	}

private:
	struct Close {
		void operator()(fscan_storage *s) const
		{
			fscan_storage_destroy(s);
		}
	};
	std::string root_, queue_dir_, state_dir_, share_dir_, share_marker_;
	long min_free_mb_;
	const fscan_storage_ops *ops_;
	std::unique_ptr<fscan_storage, Close> st_;
	Status share_error(int rc) const;
};

} // namespace facescan::daemon
