// The slow half of a scan, off the event loop: capture, reconstruction and writing (spool, then
// share) of one scan, or the delivery of spooled scans between scans, one job at a time in one
// worker thread. The job never touches the daemon's state: it posts typed messages to the
// loop's Mailbox, and its last message says it is done, so the loop joins a thread that is
// returning, never one that still works.
#pragma once

#include "daemon/daemon.hpp"
#include "daemon/spool.hpp"

#include <atomic>
#include <deque>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <utility>
#include <variant>
#include <vector>

namespace facescan::daemon {

/// What a job tells the loop, one struct per kind.
namespace job {
struct Captured {
	double ms = 0;
	std::string text;  // the progress line
	TriggerReport report;
};
struct Reconstructed {
	double ms = 0;
	std::string text;
	long vertices = 0;
	long faces = 0;
	std::vector<std::pair<std::string, double>> stage_ms;
	std::vector<std::string> warnings;  // a suspect scan, said where the operator looks
};
/// Last message of a scan: spooled (the commit point), and on the share when `delivered`.
struct Written {
	double ms = 0;
	bool delivered = false;
	std::vector<std::string> files;  // where they landed on the share
	std::string spool_reason;        // why not, when not delivered
};
/// Last message of a failed scan.
struct Failed {
	std::string stage;  // capturing, reconstructing, writing
	std::string why;
	bool hardware = false;  // the booth itself is suspect (MCU, cameras)
};
/// Last message of a delivery job.
struct DeliveryDone {
	std::vector<daemon::Delivered> scans;
	std::string error;  // the share's failure, "" when the queue emptied (or the job was stopped)
};
using Message = std::variant<Captured, Reconstructed, Written, Failed, DeliveryDone>;
} // namespace job

/// Worker → loop: a locked queue and an eventfd the loop polls.
class Mailbox {
public:
	Mailbox() = default;
	~Mailbox();
	Mailbox(const Mailbox &) = delete;
	Mailbox &operator=(const Mailbox &) = delete;

	Status open();
	int fd() const
	{
		return fd_;
	}
	/// Thread-safe.
	void post(job::Message m);
	/// Wakes the loop without a message (request_stop). Thread- and signal-safe.
	void wake();
	/// Everything posted so far, oldest first.
	std::deque<job::Message> take();

private:
	int fd_ = -1;
	std::mutex mu_;
	std::deque<job::Message> q_;
};

/// "; capture kept in DIR" when a capture set of the scan is in <spool_dir>/captures, else "".
std::string capture_kept(const std::string &spool_dir, const std::string &base);

/// Runs one job at a time in its own thread.
class Worker {
public:
	Worker(const Config &cfg, Backends &be, Spool &spool, Mailbox &mailbox)
		: cfg_(cfg), be_(be), spool_(spool), mailbox_(mailbox)
	{
	}
	~Worker()
	{
		join();
	}
	Worker(const Worker &) = delete;
	Worker &operator=(const Worker &) = delete;

	bool running() const
	{
		return thread_.joinable();
	}
	bool delivering() const
	{
		return running() && delivery_;
	}
	/// Capture, reconstruct and write the scan of `record` (the daemon's record of it: scan_id,
	/// patient_id, base, started_utc, DICOM fields). Only when !running().
	void start_scan(nlohmann::json record);
	/// Delivers spooled scans (and retries the PACS). Only when !running().
	void start_delivery();
	/// Asks a running delivery to stop after the scan it is delivering: a new scan waits for it.
	void stop_delivery()
	{
		stop_delivery_ = true;
	}
	/// Joins the thread: immediate after the job's last message, a wait otherwise (shutdown).
	void join()
	{
		if (thread_.joinable())
			thread_.join();
	}

private:
	void scan(const nlohmann::json &rec);
	void deliver();
	void keep_capture(const std::string &base, const Capture &cap);

	const Config &cfg_;
	Backends &be_;
	Spool &spool_;
	Mailbox &mailbox_;
	std::thread thread_;
	bool delivery_ = false;
	std::atomic<bool> stop_delivery_{false};
};

} // namespace facescan::daemon
