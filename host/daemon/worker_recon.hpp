// The reconstruction in its own process: the daemon's Reconstructor for recon_backend =
// pipeline. Each scan's capture set is on disk (the simulated and replay cameras leave it
// there; frames from real cameras are written to <spool>/captures/<scan>/ with the booth's
// calibration), and `facescan recon` runs on it as a child process with an address-space limit
// (RLIMIT_AS) and a deadline after which it is killed. Its crash, its timeout or its memory
// limit fail the scan with that reason; the daemon lives on, and the capture set stays in
// <spool>/captures/<scan>/ for an offline retry (`facescan recon DIR -o OUT.drc`).
#pragma once

#include "daemon/backends.hpp"

#include <string>

namespace facescan::daemon {

struct WorkerParams {
	std::string program;           // the `facescan` binary (its `recon` verb is the worker)
	std::string calibration_file;  // for frames that come without a capture set
	std::string pattern_id;        // the booth's slide; "" = this build's default
	std::string spool_dir;         // captures/ and work/ live here
	int timeout_ms = 600000;       // killed after this
	int memory_mb = 4096;          // RLIMIT_AS of the child; 0: none
	bool keep_captures = false;    // keep the written set after a success too
};

class WorkerReconstructor : public Reconstructor {
public:
	explicit WorkerReconstructor(WorkerParams params) : p_(std::move(params))
	{
	}
	std::string backend_name() const override
	{
		return "pipeline";
	}
	/// -ETIMEDOUT killed at its deadline, -ENOMEM out of memory under its limit, -ECHILD
	/// crashed (a signal), -EIO failed with its own message, or the capture's write error.
	/// Every failure message says where the capture set was kept.
	/// The set the worker ran on stays in <spool_dir>/captures/<scan_name> until release(): a
	/// daemon killed before the scan is spooled leaves it there for an offline retry.
	Status run(const Capture &capture, ReconOutput *ret_output) override;
	/// Removes <spool_dir>/captures/<scan_name> (what run() kept), unless keep_captures.
	void release(const std::string &scan_name) override;

private:
	WorkerParams p_;
};

/// The outcome of one child process run by run_with_limits().
struct ChildResult {
	bool timed_out = false;
	int exit_code = -1;   // when it exited
	int signal = 0;       // when a signal ended it
	std::string stderr_tail; // its last <= 16 KiB of stderr
};

/// Runs argv[0] with argv (stdout to /dev/null, stderr captured) under an address-space limit
/// of memory_mb (0: none), killing it (SIGKILL) after timeout_ms. The child dies with us
/// (PR_SET_PDEATHSIG). 0 or -errno when it could not be started.
Status run_with_limits(const std::vector<std::string> &argv, int timeout_ms, int memory_mb, ChildResult *ret);

} // namespace facescan::daemon
