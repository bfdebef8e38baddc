#include "daemon/scan_journal.hpp"

#include "capture/capture_set.hpp"
#include "daemon/log.hpp"
#include "daemon/scan_job.hpp"

#include <algorithm>
#include <unistd.h>

namespace facescan::daemon {

using json = nlohmann::json;

namespace {

// A state file of ours (a few kB): parsed if it is a regular file under 1 MiB, else null.
json read_small_json(const std::string &path)
{
	std::string text;
	if (!read_regular_file(path, 1 << 20, &text).ok())
		return json();
	return json::parse(text, nullptr, false, true);
}

} // namespace

void ScanJournal::save_last()
{
	Status s = write_file_atomic(spool_.state_dir(), "last.json", last_.dump(1) + "\n");
	if (!s.ok())
		log(LOG_WARNING, "cannot save the last scan's record: %s", s.message().c_str());
}

void ScanJournal::save_current(const json &record, State state)
{
	json rec = record;
	rec["state"] = state_name(state);
	Status s = write_file_atomic(spool_.state_dir(), "current.json", rec.dump(1) + "\n");
	if (!s.ok())
		log(LOG_WARNING, "cannot save the running scan's record: %s", s.message().c_str());
}

void ScanJournal::finish(const json &record)
{
	last_ = record;
	save_last();
	unlink((spool_.state_dir() + "/current.json").c_str());
}

void ScanJournal::delivered(const std::string &scan_id, const std::vector<std::string> &paths)
{
	if (last_.value("scan_id", "") != scan_id)
		return;
	last_["state"] = "delivered";
	last_["files"] = paths;
	last_.erase("spool_reason");
	save_last();
}

void ScanJournal::recover(const std::string &share_dir, const std::string &spool_dir, std::vector<std::string> interrupted)
{
	json j = read_small_json(spool_.state_dir() + "/last.json");
	if (j.is_object())
		last_ = j;
	// The scan the previous daemon did not finish. The spool decides what became of it: queued
	// (delivered next), on the share already, or lost before it was spooled.
	json cur = read_small_json(spool_.state_dir() + "/current.json");
	if (cur.is_object() && cur.contains("scan_id")) {
		const std::string st = cur.value("state", "?");
		const std::string id = cur.value("scan_id", "");
		const std::string base = cur.value("base", "");
		const bool on_share = !base.empty() &&
				      access((share_dir + "/" + cur.value("patient_id", "") + "/" + base + ".json").c_str(),
					     F_OK) == 0;
		cur.erase("base");
		if (spool_.queued(id)) {
			log(LOG_WARNING, "scan %s: the daemon stopped before delivering it; delivering it from the spool",
			    id.c_str());
			cur["state"] = "spooled";
			cur["spool_reason"] = "the daemon stopped while delivering it";
		} else if (st == "writing" && on_share &&
			   std::find(interrupted.begin(), interrupted.end(), id) == interrupted.end()) {
			log(LOG_INFO, "scan %s: delivered before the daemon stopped", id.c_str());
			cur["state"] = "delivered";
		} else {
			const std::string kept = capture_kept(spool_dir, base);
			log(LOG_ERR, "scan %s: interrupted while %s (daemon stopped); reported failed%s", id.c_str(),
			    st.c_str(), kept.c_str());
			cur["state"] = "failed";
			cur["failed_stage"] = st;
			cur["error"] = "interrupted while " + st + ": the daemon stopped; scan again" + kept;
		}
		interrupted.erase(std::remove(interrupted.begin(), interrupted.end(), id), interrupted.end());
		last_ = cur;
		save_last();
	}
	unlink((spool_.state_dir() + "/current.json").c_str());
	for (const std::string &id : interrupted) {
		log(LOG_ERR, "scan %s: interrupted while writing (daemon stopped); reported failed", id.c_str());
		if (last_.value("scan_id", "") != id || last_.value("state", "") != "failed") {
			last_ = {{"scan_id", id},
				 {"state", "failed"},
				 {"failed_stage", "writing"},
				 {"error", "interrupted while writing: the daemon stopped; scan again"}};
			save_last();
		}
	}
}

} // namespace facescan::daemon
