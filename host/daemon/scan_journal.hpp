// What `facescan last` reports, kept across crashes. <spool>/state/current.json is the scan in
// flight, rewritten at each stage, so that a daemon that dies mid-scan (crash, kill -9) reports
// it at the next start instead of forgetting it; <spool>/state/last.json is the last finished
// scan. Both are written atomically; the journal is touched by the event loop only.
#pragma once

#include "daemon/spool.hpp"
#include "daemon/state_machine.hpp"

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace facescan::daemon {

class ScanJournal {
public:
	explicit ScanJournal(const Spool &spool) : spool_(spool)
	{
	}

	/// Reads last.json, then settles what a dead daemon left: the scan in current.json (queued:
	/// delivered next; on the share: delivered; else failed) and the spool entries interrupted
	/// while being written (`interrupted`, from Spool::recover). Logs each.
	void recover(const std::string &share_dir, const std::string &spool_dir, std::vector<std::string> interrupted);
	/// The running scan's record at `state`, for the next start should this daemon die.
	void save_current(const nlohmann::json &record, State state);
	/// The scan ended (record["state"] says how): it becomes `last`, current.json goes.
	void finish(const nlohmann::json &record);
	/// A spooled scan reached the share: `last` says so when it is that scan.
	void delivered(const std::string &scan_id, const std::vector<std::string> &paths);
	/// The last finished scan, or null.
	const nlohmann::json &last() const
	{
		return last_;
	}

private:
	void save_last();

	const Spool &spool_;
	nlohmann::json last_;
};

} // namespace facescan::daemon
