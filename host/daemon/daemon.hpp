// facescand's core: the event loop (control socket, MCU events, worker messages, deadlines) in
// the calling thread, and a worker thread for the slow stages of a scan (capture,
// reconstruction, writing) and for deliveries of spooled scans (daemon.cpp says how the parts
// fit; docs/daemon.md draws them).
// Ownership of the booth follows the state: the worker calls the MCU only while capturing and
// the cameras and reconstructor only while it runs; the loop calls the MCU otherwise.
#pragma once

#include "common/status.hpp"
#include "daemon/backends.hpp"
#include "daemon/config.hpp"
#include "daemon/state_machine.hpp"
#include "facescan/storage.h"

#include <functional>
#include <memory>

namespace facescan::daemon {

struct Backends {
	std::unique_ptr<Mcu> mcu;
	std::unique_ptr<Cameras> cameras;
	std::unique_ptr<Reconstructor> recon;
	/// The storage driver's backend under the spool (share_dir, spool_dir): the real files.
	/// In-process tests may pass another table (the fake, or one that slows the real one).
	const fscan_storage_ops *storage = &fscan_storage_posix_ops;
};

class Daemon {
public:
	Daemon(Config config, Backends backends);
	~Daemon();
	Daemon(const Daemon &) = delete;
	Daemon &operator=(const Daemon &) = delete;

	/// Where "READY=1", "STATUS=...", "WATCHDOG=1", "STOPPING=1" go (sd_notify in facescand).
	void set_notify(std::function<void(const std::string &)> notify);
	/// Pings the watchdog every usec/2 while no stage overruns stage_timeout_ms (0: off).
	void set_watchdog_usec(uint64_t usec);

	/// Recovers the spool, opens the booth (a missing MCU or camera is an error state, not a
	/// failure to start), binds the socket. Fails on a bad spool or socket.
	Status start();
	/// Serves until request_stop(); then finishes the running scan and returns.
	Status run();
	/// Thread- and signal-safe.
	void request_stop();
	/// The current state, readable from any thread.
	State state() const;

	struct Impl;

private:
	std::unique_ptr<Impl> impl_;
};

} // namespace facescan::daemon
