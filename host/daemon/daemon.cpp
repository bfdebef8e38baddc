// The event loop of facescand and the scan it drives. The parts with one job each live beside
// it: ControlServer (the socket and its clients), ScanJournal (current.json / last.json and
// crash recovery), Worker (the scan's slow stages and deliveries, in a thread), Spool, and the
// StateMachine. This file owns the state of the booth and is the only one that changes it.
//
// One poll() waits on one source per handler: the worker's mailbox, the listening socket, the
// MCU's event fds (its link, the GPIO button line) and each client; then the deadlines that are due
// fire, from one table (deadlines()) that also gives poll its timeout. Nothing in the loop
// waits for the worker: its jobs end with a message, and the loop acts on that message.
#include "daemon/daemon.hpp"

#include "common/version.hpp"
#include "daemon/clinic_output.hpp"
#include "daemon/clock.hpp"
#include "daemon/control_server.hpp"
#include "daemon/log.hpp"
#include "daemon/output.hpp"
#include "daemon/patient_id.hpp"
#include "daemon/scan_job.hpp"
#include "daemon/scan_journal.hpp"
#include "daemon/spool.hpp"
#include "viewer/viewer.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fcntl.h>
#include <poll.h>
#include <sys/file.h>
#include <unistd.h>

namespace facescan::daemon {

using json = nlohmann::json;

namespace {

constexpr int kRecoverEveryMs = 1000;
// A deadline that is due whenever it is read: fire_due() takes `now` before it builds the table,
// so Clock::now() in the table would always be a little late.
constexpr Clock::time_point kAtOnce{};

int ms_until(Clock::time_point t)
{
	auto d = std::chrono::duration_cast<std::chrono::milliseconds>(t - Clock::now()).count();
	return d < 0 ? 0 : static_cast<int>(d);
}

// Takes an exclusive flock on `path` (created if missing) without waiting and writes our pid
// into it. -EBUSY names the pid that holds it. The kernel drops the lock when we die, however.
Status take_lock(const std::string &path, const std::string &what, int *ret_fd)
{
	int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0640);
	if (fd < 0)
		return Status::error(errno, "lock " + path + ": " + std::strerror(errno));
	if (flock(fd, LOCK_EX | LOCK_NB) < 0) {
		int err = errno;
		char pid[32] = {};
		if (pread(fd, pid, sizeof pid - 1, 0) < 0)
			pid[0] = 0;
		::close(fd);
		if (err == EWOULDBLOCK) {
			std::string p(pid);
			while (!p.empty() && (p.back() == '\n' || p.back() == ' '))
				p.pop_back();
			return Status::error(EBUSY, "another facescand" + (p.empty() ? "" : " (pid " + p + ")") +
							    " is running on " + what + "; refusing to start");
		}
		return Status::error(err, "lock " + path + ": " + std::strerror(err));
	}
	std::string me = std::to_string(getpid()) + "\n";
	if (ftruncate(fd, 0) < 0 || pwrite(fd, me.data(), me.size(), 0) < 0) {
		// the pid is a courtesy for the message above; the lock is what counts
	}
	*ret_fd = fd;
	return Status();
}

} // namespace

struct Daemon::Impl {
	Config cfg;
	Backends be;
	Spool spool;
	StateMachine sm;
	std::atomic<State> state_pub{State::idle};
	std::function<void(const std::string &)> notify = [](const std::string &) {};
	uint64_t watchdog_usec = 0;
	std::atomic<bool> stop{false};
	int lock_fd = -1;        // flock on <spool>/facescand.lock: one daemon per spool
	int socket_lock_fd = -1; // flock on <socket>.lock: one daemon per socket

	ControlServer control{cfg, [this](Client &c, const Request &r) { on_request(c, r); }};
	ScanJournal journal{spool};
	Mailbox mailbox;
	Worker worker{cfg, be, spool, mailbox};  // after what it uses: destroyed (joined) first
	viewer::Server viewer; // the web viewer of the share, when viewer_port is set

	// the scan in flight
	json current;            // its record: what `last` reports once it ends
	std::string fault;       // why we are in error
	bool hardware_fault = false;
	bool capture_waits = false;   // fired while a delivery ran: the capture starts when it ends
	Clock::time_point stage_start = Clock::now();

	// the deadlines (see deadlines())
	Clock::time_point arm_deadline;
	Clock::time_point next_recover = Clock::now();
	Clock::time_point next_delivery = Clock::now();
	Clock::time_point next_ping = Clock::now();

	Impl(Config c, Backends b)
		: cfg(std::move(c)), be(std::move(b)),
		  spool(cfg.spool_dir, cfg.share_dir, cfg.min_free_mb, cfg.share_marker, be.storage)
	{
	}
	~Impl()
	{
		worker.join();
		control.shutdown();
		if (socket_lock_fd >= 0)
			::close(socket_lock_fd);
		if (lock_fd >= 0)
			::close(lock_fd);
		if (be.mcu)
			be.mcu->close();
	}

	// ---- state -------------------------------------------------------------------------

	// Applies an event the loop has already decided is legal. A refusal here is a bug in the
	// daemon, not in the booth: it is logged with the state and the event, and the booth goes
	// to error (failed or fault, whichever the state allows) so the operator sees it and the
	// recovery timer brings it back to idle. Not an assert: a booth daemon must stay up, and a
	// release build would otherwise carry on in a state nobody chose.
	void transition(Event e)
	{
		Status s = sm.apply(e);
		if (!s.ok()) {
			log(LOG_ERR, "bug: event %s refused in state %s: %s", event_name(e), state_name(sm.state()),
			    s.message().c_str());
			if (sm.state() != State::error &&
			    sm.apply(sm.busy() && sm.state() != State::armed ? Event::failed : Event::fault).ok()) {
				fault = std::string("internal error: event ") + event_name(e) + " refused";
				next_recover = Clock::now();
			}
		}
		state_pub = sm.state();
	}

	std::string sid() const
	{
		return current.value("scan_id", std::string("-"));
	}

	void progress(const std::string &stage, const std::string &text)
	{
		if (sm.busy())
			journal.save_current(current, sm.state());
		log(LOG_INFO, "scan %s: %s", sid().c_str(), text.c_str());
		notify("STATUS=" + std::string(state_name(sm.state())) + ": scan " + sid() + " " + stage);
		control.tell_followers(sid(), {{"event", "progress"}, {"scan_id", sid()}, {"state", state_name(sm.state())},
					       {"message", text}},
				       false);
	}

	json status_json() const
	{
		json j = {{"ok", true},
			  {"state", state_name(sm.state())},
			  {"mode", mode_name(cfg.mode)},
			  {"version", version()},
			  {"spool_pending", spool.pending()},
			  {"mcu", be.mcu->is_open() ? "connected" : "disconnected"},
			  {"firmware", be.mcu->is_open() ? be.mcu->firmware_version() : ""},
			  {"camera_backend", be.cameras->backend_name()},
			  {"recon_backend", be.recon->backend_name()}};
		if (sm.busy()) {
			j["scan_id"] = sid();
			j["stage_elapsed_ms"] = static_cast<long>(ms_since(stage_start));
		}
		if (sm.state() == State::error)
			j["fault"] = fault;
		return j;
	}

	// ---- control requests ----------------------------------------------------------------

	void on_request(Client &c, const Request &req)
	{
		switch (req.cmd) {
		case Request::Cmd::status:
			control.send(c, status_json());
			break;
		case Request::Cmd::last:
			control.send(c, {{"ok", true}, {"last", journal.last()}});
			break;
		case Request::Cmd::cancel:
			if (sm.state() != State::armed) {
				control.reply_error(c, "not_armed",
						    std::string("nothing armed (state ") + state_name(sm.state()) + ")");
				break;
			}
			be.mcu->abort();
			transition(Event::disarm);
			progress("cancelled", "cancelled before the trigger");
			finish_record("cancelled", "");
			control.send(c, {{"ok", true}, {"state", state_name(sm.state())}});
			break;
		case Request::Cmd::button: {
			if (cfg.mode != Mode::booth) {
				// It would be ignored (on_button): say so instead of answering ok.
				control.reply_error(c, "unsupported", "the button starts scans only in booth mode (mode = clinic)");
				break;
			}
			Status b = be.mcu->simulate_button();
			if (!b.ok())
				control.reply_error(c, "unsupported", b.message());
			else
				control.send(c, {{"ok", true}});
			break;
		}
		case Request::Cmd::scan:
			on_scan_request(c, req);
			break;
		}
	}

	void on_scan_request(Client &c, const Request &req)
	{
		Status s = validate_patient_id(req.patient);
		if (!s.ok()) {
			log(LOG_WARNING, "control: scan refused: %s", s.message().c_str());
			control.reply_error(c, "bad_patient_id", s.message());
			return;
		}
		s = begin_scan(req.patient);
		if (!s.ok()) {
			control.reply_error(c, s.code() == -EBUSY ? "busy" : "unavailable", s.message());
			return;
		}
		// The request's DICOM fields (checked by parse_request) ride with the scan's record.
		for (const auto &[k, v] : {std::pair{"dicom_name", &req.name}, {"dicom_accession", &req.accession},
					   {"dicom_study_uid", &req.study_uid}})
			if (!v->empty())
				current[k] = *v;
		std::string id = sid();
		if (req.wait)
			c.wait_scan = id;
		control.send(c, {{"ok", true}, {"scan_id", id}, {"state", state_name(sm.state())}});
		if (cfg.mode == Mode::clinic)
			fire();
	}

	// ---- the scan ------------------------------------------------------------------------

	Status begin_scan(const std::string &patient)
	{
		// A spool we cannot write would lose the scan after capture and reconstruction.
		if (!sm.busy() && sm.state() != State::error) {
			Status w = spool.writable();
			if (!w.ok()) {
				log(LOG_ERR, "scan refused: %s", w.message().c_str());
				return Status::error(EAGAIN, "unavailable: " + w.message());
			}
		}
		// Refused here, not by a transition: a request outside idle is the client's, not a bug.
		Status s = sm.apply(Event::request);
		if (!s.ok()) {
			if (s.code() == -EAGAIN)
				return Status::error(EAGAIN, "unavailable: " + fault);
			if (sm.busy())
				return Status::error(EBUSY, "busy: scan " + sid() + " is " + state_name(sm.state()));
			return s;
		}
		state_pub = sm.state();
		// A delivery of spooled scans is not a scan: it stops after the scan it is delivering,
		// and the capture, if fired before, waits for that (fire()).
		if (worker.delivering())
			worker.stop_delivery();
		auto now = std::chrono::system_clock::now();
		const std::string id = new_scan_id();
		current = {{"scan_id", id},
			   {"patient_id", patient},
			   {"base", output_base(now, id)},
			   {"started_utc", utc_iso(now)},
			   {"state", "armed"},
			   {"stage_ms", json::object()}};
		stage_start = Clock::now();
		Timing t{cfg.projector_settle_us, cfg.exposure_us, cfg.texture_exposure_us};
		s = be.mcu->arm(t);
		if (!s.ok()) {
			fail_scan("armed", "arm: " + s.message(), true);
			return Status::error(EAGAIN, "unavailable: " + s.message());
		}
		// Requests queued before the trigger: in booth mode the firmware fires on the press.
		if (be.cameras->prepare_at_arm()) {
			s = be.cameras->prepare();
			if (!s.ok()) {
				be.mcu->abort();
				fail_scan("armed", "cameras: " + s.message(), true);
				return Status::error(EAGAIN, "unavailable: cameras: " + s.message());
			}
		}
		arm_deadline = Clock::now() + std::chrono::milliseconds(cfg.arm_timeout_ms);
		progress("armed", cfg.mode == Mode::booth ? "armed, waiting for the button" : "armed");
		return Status();
	}

	void fire()
	{
		if (sm.state() != State::armed) {
			log(LOG_ERR, "bug: fire in state %s", state_name(sm.state()));
			return;
		}
		transition(Event::fire);
		stage_start = Clock::now();
		current["state"] = "capturing";
		progress("capturing", "[1/3] capturing");
		if (worker.running()) {
			capture_waits = true;
			log(LOG_INFO, "scan %s: the capture waits for the delivery of a spooled scan to end", sid().c_str());
			return;
		}
		worker.start_scan(current);
	}

	void on_button()
	{
		if (cfg.button_source == ButtonSource::none) {
			log(LOG_INFO, "button pressed: ignored (button_source = none)");
			return;
		}
		if (cfg.mode != Mode::booth) {
			log(LOG_INFO, "button pressed: ignored in clinic mode");
			return;
		}
		if (sm.state() == State::idle) {
			Status s = begin_scan(cfg.booth_patient_id);
			if (!s.ok()) {
				log(LOG_WARNING, "button pressed: %s", s.message().c_str());
				return;
			}
		}
		if (sm.state() == State::armed) {
			fire();
			return;
		}
		log(LOG_INFO, "button pressed: ignored, %s", state_name(sm.state()));
	}

	void finish_record(const std::string &outcome, const std::string &error)
	{
		current["state"] = outcome;
		current["finished_utc"] = utc_iso(std::chrono::system_clock::now());
		if (!error.empty())
			current["error"] = error;
		current.erase("base");
		journal.finish(current);
		json done = {{"event", "done"}, {"ok", outcome == "delivered" || outcome == "spooled"}, {"scan", current}};
		control.tell_followers(sid(), done, true);
	}

	void fail_scan(const std::string &stage, const std::string &why, bool hardware)
	{
		current["failed_stage"] = stage;
		transition(Event::failed);
		fault = why;
		hardware_fault = hardware;
		log(LOG_ERR, "scan %s: failed while %s: %s", sid().c_str(), stage.c_str(), why.c_str());
		notify("STATUS=error: scan " + sid() + " failed while " + stage);
		finish_record("failed", why);
		if (hardware)
			be.mcu->abort();
		next_recover = Clock::now();
	}

	// ---- the worker's messages -------------------------------------------------------------

	void on_mailbox()
	{
		for (job::Message &m : mailbox.take())
			std::visit([this](auto &msg) { on_job(msg); }, m);
	}

	void on_job(job::Captured &m)
	{
		transition(Event::captured);
		stage_start = Clock::now();
		current["stage_ms"]["capture"] = m.ms;
		current["trigger_report"] = m.report.raw;
		current["state"] = "reconstructing";
		progress("reconstructing", m.text + "; [2/3] reconstructing");
	}

	void on_job(job::Reconstructed &m)
	{
		transition(Event::reconstructed);
		stage_start = Clock::now();
		current["stage_ms"]["reconstruct"] = m.ms;
		current["vertices"] = m.vertices;
		current["faces"] = m.faces;
		current["recon_stage_ms"] = json::object();
		for (const auto &st : m.stage_ms)
			current["recon_stage_ms"][st.first] = st.second;
		// A suspect scan (wrong pattern, a camera that adds nothing) is said where the
		// operator looks: the log and `facescan last`, not only the metadata.
		if (!m.warnings.empty()) {
			current["warnings"] = m.warnings;
			for (const std::string &w : m.warnings)
				log(LOG_WARNING, "scan %s: %s", sid().c_str(), w.c_str());
		}
		current["state"] = "writing";
		progress("writing", m.text + "; [3/3] writing");
	}

	void on_job(job::Written &m)
	{
		worker.join(); // its last message: the thread is returning
		transition(Event::written);
		current["stage_ms"]["write"] = m.ms;
		current["files"] = m.files;
		const std::string outcome = m.delivered ? "delivered" : "spooled";
		double total = 0;
		for (auto &v : current["stage_ms"])
			total += v.get<double>();
		if (m.delivered) {
			log(LOG_INFO, "scan %s: [3/3] delivered to the share in %ld ms (total %ld ms)", sid().c_str(),
			    static_cast<long>(m.ms), static_cast<long>(total));
		} else {
			current["spool_reason"] = m.spool_reason;
			log(LOG_WARNING, "scan %s: [3/3] spooled, the share cannot take it yet (%s); total %ld ms",
			    sid().c_str(), m.spool_reason.c_str(), static_cast<long>(total));
			next_delivery = Clock::now() + std::chrono::milliseconds(cfg.spool_retry_ms);
		}
		notify("STATUS=idle: last scan " + sid() + " " + outcome);
		finish_record(outcome, "");
	}

	void on_job(job::Failed &m)
	{
		worker.join(); // its last message: the thread is returning
		fail_scan(m.stage, m.why, m.hardware);
		try_recover();
	}

	void on_job(job::DeliveryDone &m)
	{
		worker.join(); // its last message: the thread is returning
		for (const Delivered &d : m.scans) {
			log(LOG_INFO, "scan %s: spooled scan delivered to the share", d.scan_id.c_str());
			journal.delivered(d.scan_id, d.paths);
		}
		if (!m.error.empty())
			next_delivery = Clock::now() + std::chrono::milliseconds(cfg.spool_retry_ms);
		if (capture_waits) {
			capture_waits = false;
			if (sm.state() == State::capturing) {
				stage_start = Clock::now();
				worker.start_scan(current);
			}
		}
	}

	// ---- the MCU -------------------------------------------------------------------------

	// The loop reads the MCU's events unless the worker is firing it (capturing: from the fire
	// until the frames are in, the capture waiting for a delivery included) or the booth is in
	// error (recovery reopens it; a press meanwhile is not a scan).
	bool mcu_is_ours() const
	{
		return sm.state() != State::capturing && sm.state() != State::error;
	}

	void on_mcu()
	{
		if (!mcu_is_ours())
			return;
		std::vector<McuEvent> events;
		be.mcu->poll_events(&events);
		if (!be.mcu->is_open() && events.empty() &&
		    (sm.state() == State::idle || sm.state() == State::armed))
			events.push_back({McuEvent::Type::disconnected, "link closed"});
		for (const McuEvent &e : events) {
			switch (e.type) {
			case McuEvent::Type::button:
				on_button();
				break;
			case McuEvent::Type::fault:
				log(LOG_WARNING, "MCU reports a fault: %s", e.detail.c_str());
				break;
			case McuEvent::Type::disconnected:
				log(LOG_ERR, "MCU link lost: %s", e.detail.c_str());
				be.mcu->close();
				if (sm.state() == State::armed) {
					fail_scan("armed", "MCU link lost", true);
				} else if (sm.state() == State::idle) {
					transition(Event::fault);
					fault = "MCU link lost";
					hardware_fault = false;
					notify("STATUS=error: MCU link lost");
				}
				break;
			}
		}
	}

	// ---- deadlines -----------------------------------------------------------------------

	void try_recover()
	{
		next_recover = Clock::now() + std::chrono::milliseconds(kRecoverEveryMs);
		if (sm.state() != State::error || worker.running())
			return;
		if (!be.mcu->is_open()) {
			Status s = be.mcu->open();
			if (!s.ok()) {
				fault = "MCU: " + s.message();
				return;
			}
			log(LOG_INFO, "MCU connected: %s", be.mcu->firmware_version().c_str());
		}
		if (hardware_fault) {
			Status s = be.cameras->open();
			if (!s.ok()) {
				fault = "cameras: " + s.message();
				return;
			}
		}
		transition(Event::recovered);
		fault.clear();
		hardware_fault = false;
		log(LOG_INFO, "recovered: idle");
		notify("STATUS=idle");
	}

	void on_arm_timeout()
	{
		be.mcu->abort();
		transition(Event::disarm);
		log(LOG_INFO, "scan %s: no button press within %d ms, disarmed", sid().c_str(), cfg.arm_timeout_ms);
		finish_record("cancelled", "no button press in time");
	}

	void start_delivery()
	{
		next_delivery = Clock::now() + std::chrono::milliseconds(cfg.spool_retry_ms);
		worker.start_delivery();
	}

	void ping_watchdog()
	{
		next_ping = Clock::now() + std::chrono::microseconds(watchdog_usec / 2);
		// A stage that overruns means a hung worker: stop pinging and let systemd restart us.
		if (!sm.busy() || ms_since(stage_start) < cfg.stage_timeout_ms)
			notify("WATCHDOG=1");
		else
			log(LOG_CRIT, "scan %s: stage %s overran %d ms, watchdog pings stopped", sid().c_str(),
			    state_name(sm.state()), cfg.stage_timeout_ms);
	}

	void expire_clients()
	{
		control.expire_clients();
	}

	// Every timed thing the loop does, with the condition under which it is armed. poll's
	// timeout and the firing both read this one table, so a deadline cannot be armed in one
	// and forgotten in the other. Each action moves its own deadline or disarms it.
	struct Deadline {
		Clock::time_point when;
		void (Impl::*fire)();
	};

	std::vector<Deadline> deadlines() const
	{
		std::vector<Deadline> d;
		if (sm.state() == State::armed)
			d.push_back({arm_deadline, &Impl::on_arm_timeout});
		if (sm.state() == State::error && !worker.running())
			d.push_back({next_recover, &Impl::try_recover});
		if (!sm.busy() && !worker.running() && (spool.pending() > 0 || clinic::pacs_pending(cfg)))
			d.push_back({next_delivery, &Impl::start_delivery});
		if (mcu_is_ours()) {
			// A link a command found down has no fd left to wake us: on_mcu makes it the fault.
			bool lost = !be.mcu->is_open() && (sm.state() == State::idle || sm.state() == State::armed);
			int due = lost ? 0 : be.mcu->events_due_ms(); // what the fds would not show
			if (due == 0)
				d.push_back({kAtOnce, &Impl::on_mcu});
			else if (due > 0)
				d.push_back({Clock::now() + std::chrono::milliseconds(due), &Impl::on_mcu});
		}
		if (watchdog_usec)
			d.push_back({next_ping, &Impl::ping_watchdog});
		if (auto t = control.next_deadline())
			d.push_back({*t, &Impl::expire_clients});
		return d;
	}

	int poll_timeout() const
	{
		auto soonest = Clock::now() + std::chrono::milliseconds(1000);
		for (const Deadline &d : deadlines())
			soonest = std::min(soonest, d.when);
		return ms_until(soonest);
	}

	void fire_due()
	{
		// One at a time, the table rebuilt after each: an action changes what is armed. At most
		// 16 a turn, so that a deadline that failed to move itself cannot starve the sockets.
		for (int n = 0; n < 16; n++) {
			auto now = Clock::now();
			const Deadline *due = nullptr;
			std::vector<Deadline> table = deadlines();
			for (const Deadline &d : table)
				if (d.when <= now && (!due || d.when < due->when))
					due = &d;
			if (!due)
				return;
			(this->*(due->fire))();
		}
	}

	// ---- the loop ------------------------------------------------------------------------

	Status run_once()
	{
		std::vector<pollfd> fds;
		fds.push_back({mailbox.fd(), POLLIN, 0});
		fds.push_back({control.listen_fd(), POLLIN, 0});
		const size_t first_mcu = fds.size();
		if (mcu_is_ours())
			for (int fd : be.mcu->event_fds())
				fds.push_back({fd, POLLIN, 0});
		const size_t first_client = fds.size();
		for (const auto &c : control.clients())
			fds.push_back({c->fd, POLLIN, 0});
		int r = poll(fds.data(), fds.size(), poll_timeout());
		if (r < 0 && errno != EINTR)
			return Status::error(errno, std::string("poll: ") + std::strerror(errno));
		if (r > 0) {
			if (fds[0].revents)
				on_mailbox();
			if (std::any_of(fds.begin() + first_mcu, fds.begin() + first_client,
					[](const pollfd &p) { return p.revents != 0; }))
				on_mcu();
			if (fds[1].revents)
				control.accept_clients();
			// Clients accepted just now come after the polled ones; closed ones stay until
			// close_finished(), so index i is still the client polled at i.
			for (size_t i = first_client; i < fds.size(); i++)
				if (fds[i].revents)
					control.read_client(i - first_client);
		}
		fire_due();
		control.close_finished();
		return Status();
	}
};

Daemon::Daemon(Config config, Backends backends) : impl_(std::make_unique<Impl>(std::move(config), std::move(backends)))
{
}

Daemon::~Daemon() = default;

void Daemon::set_notify(std::function<void(const std::string &)> notify)
{
	impl_->notify = std::move(notify);
}

void Daemon::set_watchdog_usec(uint64_t usec)
{
	impl_->watchdog_usec = usec;
}

State Daemon::state() const
{
	return impl_->state_pub.load();
}

void Daemon::request_stop()
{
	impl_->stop = true;
	impl_->mailbox.wake();
}

Status Daemon::start()
{
	Impl &d = *impl_;
	if (!d.be.mcu || !d.be.cameras || !d.be.recon || !d.be.storage)
		return Status::error(EINVAL, "facescand: a backend is missing");
	Status s = d.mailbox.open();
	if (!s.ok())
		return s;
	// One daemon per spool and per socket, settled before anything is touched: a second
	// daemon must not run crash recovery on a live daemon's spool.
	s = d.spool.init();
	if (!s.ok())
		return s;
	s = take_lock(d.cfg.spool_dir + "/facescand.lock", "spool " + d.cfg.spool_dir, &d.lock_fd);
	if (!s.ok())
		return s;
	s = take_lock(d.cfg.socket_path + ".lock", "socket " + d.cfg.socket_path, &d.socket_lock_fd);
	if (!s.ok())
		return s;
	s = d.spool.writable();
	if (!s.ok())
		return s;
	s = d.control.bind();
	if (!s.ok())
		return s;
	std::vector<std::string> interrupted;
	s = d.spool.recover(&interrupted);
	if (!s.ok())
		return s;
	d.journal.recover(d.cfg.share_dir, d.cfg.spool_dir, std::move(interrupted));
	size_t pending = d.spool.pending();
	if (pending)
		log(LOG_INFO, "%zu spooled scan(s) waiting for the share", pending);
	s = d.be.cameras->open();
	if (!s.ok()) {
		log(LOG_ERR, "cameras: %s", s.message().c_str());
		d.transition(Event::fault);
		d.fault = "cameras: " + s.message();
		d.hardware_fault = true;
	}
	Status m = d.be.mcu->open();
	if (!m.ok()) {
		log(LOG_ERR, "MCU: %s", m.message().c_str());
		if (d.sm.state() != State::error)
			d.transition(Event::fault);
		d.fault = "MCU: " + m.message();
	} else {
		log(LOG_INFO, "MCU connected: %s", d.be.mcu->firmware_version().c_str());
	}
	if (d.cfg.viewer_port > 0) { // a viewer that cannot start is logged; scanning goes on
		viewer::Options vo;
		vo.share_dir = d.cfg.share_dir;
		vo.bind = d.cfg.viewer_bind;
		vo.port = d.cfg.viewer_port;
		int port = 0;
		Status v = viewer::find_web_dir(&vo.web_dir);
		if (v.ok())
			v = d.viewer.start(vo, &port);
		if (v.ok())
			log(LOG_INFO, "viewer: http://%s:%d/", vo.bind.c_str(), port);
		else
			log(LOG_WARNING, "viewer: %s", v.message().c_str());
	}
	log(LOG_INFO, "facescand %s serving %s (%s mode, cameras: %s, reconstruction: %s)", version(),
	    d.cfg.socket_path.c_str(), mode_name(d.cfg.mode), d.be.cameras->backend_name().c_str(),
	    d.be.recon->backend_name().c_str());
	return Status();
}

Status Daemon::run()
{
	Impl &d = *impl_;
	d.notify("READY=1");
	d.notify(std::string("STATUS=") + state_name(d.sm.state()));
	while (!d.stop) {
		Status s = d.run_once();
		if (!s.ok())
			return s;
	}
	d.notify("STOPPING=1");
	if (d.worker.running()) {
		log(LOG_INFO, "stopping: waiting for the running stage to finish");
		// Let the worker finish and record its outcome so nothing is left half-written.
		while (d.worker.running()) {
			pollfd p = {d.mailbox.fd(), POLLIN, 0};
			poll(&p, 1, 1000);
			d.on_mailbox();
		}
	}
	log(LOG_INFO, "stopped");
	return Status();
}

} // namespace facescan::daemon
