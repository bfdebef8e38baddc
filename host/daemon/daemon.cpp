#include "daemon/daemon.hpp"

#include "capture/capture_set.hpp"
#include "common/version.hpp"
#include "daemon/control.hpp"
#include "daemon/log.hpp"
#include "daemon/output.hpp"
#include "daemon/clinic_output.hpp"
#include "viewer/viewer.hpp"
#include "daemon/patient_id.hpp"
#include "daemon/spool.hpp"

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <deque>
#include <fcntl.h>
#include <fstream>
#include <grp.h>
#include <mutex>
#include <poll.h>
#include <sstream>
#include <sys/eventfd.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <thread>
#include <unistd.h>

namespace facescan::daemon {

using json = nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

constexpr int kMaxClients = 32;
constexpr int kRecoverEveryMs = 1000;
constexpr int kMcuPollMs = 50;

double ms_since(Clock::time_point t)
{
	return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

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

// A state file of ours (a few kB): parsed if it is a regular file under 1 MiB, else null.
json read_small_json(const std::string &path)
{
	std::string text;
	if (!read_regular_file(path, 1 << 20, &text).ok())
		return json();
	return json::parse(text, nullptr, false, true);
}

// What the worker tells the loop.
struct Msg {
	enum class Kind { captured, reconstructed, finished, failed, delivered } kind;
	double ms = 0;
	std::string text;
	bool hardware = false;  // failed: the booth itself is suspect (MCU, cameras)
	json data;
};

struct Client {
	int fd = -1;
	LineReader reader;
	std::string wait_scan;  // scan id whose progress this client follows
	// A whole request must arrive by then, however slowly its bytes trickle in (slowloris);
	// renewed after each request. A client following a scan is exempt.
	Clock::time_point deadline;
	bool closing = false;
};

} // namespace

struct Daemon::Impl {
	Config cfg;
	Backends be;
	Spool spool;
	StateMachine sm;
	std::atomic<State> state_pub{State::idle};
	std::function<void(const std::string &)> notify = [](const std::string &) {};
	uint64_t watchdog_usec = 0;

	int listen_fd = -1;
	int wake_fd = -1;
	int lock_fd = -1;        // flock on <spool>/facescand.lock: one daemon per spool
	int socket_lock_fd = -1; // flock on <socket>.lock: one daemon per socket
	Clock::time_point next_refusal_log;
	long refusals_unlogged = 0;
	std::atomic<bool> stop{false};
	std::vector<std::unique_ptr<Client>> clients;

	// the scan in flight (or the last one)
	json current;          // the record `last` reports
	json last;             // the last finished scan
	std::string fault;     // why we are in error
	bool hardware_fault = false;
	Clock::time_point stage_start = Clock::now();
	Clock::time_point arm_deadline;
	Clock::time_point next_recover = Clock::now();
	Clock::time_point next_delivery = Clock::now();
	Clock::time_point next_mcu_poll = Clock::now();
	Clock::time_point next_ping = Clock::now();
	bool mcu_with_worker = false;

	viewer::Server viewer; // the web viewer of the share, when viewer_port is set
	std::thread worker;
	bool worker_running = false;
	bool worker_is_delivery = false;
	std::mutex msg_mu;
	std::deque<Msg> msgs;

	Impl(Config c, Backends b)
		: cfg(std::move(c)), be(std::move(b)), spool(cfg.spool_dir, cfg.share_dir, cfg.min_free_mb, cfg.share_marker)
	{
	}

	// ---- helpers ---------------------------------------------------------------------

	void set_state_pub()
	{
		state_pub = sm.state();
	}

	// Applies an event the loop has already decided is legal. A refusal here is a bug in the
	// daemon, not in the booth: it is logged with the state and the event, and the booth goes
	// to error (failed or fault, whichever the state allows) so the operator sees it and the
	// recovery timer brings it back to idle. Not an assert: a booth daemon must stay up, and a
	// release build would otherwise carry on in a state nobody chose.
	void transition(Event e)
	{
		Status s = sm.apply(e);
		if (s.ok()) {
			set_state_pub();
			return;
		}
		log(LOG_ERR, "bug: event %s refused in state %s: %s", event_name(e), state_name(sm.state()),
		    s.message().c_str());
		if (sm.state() != State::error) {
			Status f = sm.apply(sm.busy() && sm.state() != State::armed ? Event::failed : Event::fault);
			if (f.ok()) {
				fault = std::string("internal error: event ") + event_name(e) + " in state " +
					state_name(sm.state());
				next_recover = Clock::now();
			}
		}
		set_state_pub();
	}

	void post(Msg m)
	{
		{
			std::lock_guard<std::mutex> lock(msg_mu);
			msgs.push_back(std::move(m));
		}
		uint64_t one = 1;
		if (write(wake_fd, &one, sizeof one) < 0) {
			// counter saturated: the loop is woken anyway
		}
	}

	std::string sid() const
	{
		return current.value("scan_id", std::string("-"));
	}

	void progress(const std::string &stage, const std::string &text)
	{
		if (sm.busy())
			save_current();
		log(LOG_INFO, "scan %s: %s", sid().c_str(), text.c_str());
		notify("STATUS=" + std::string(state_name(sm.state())) + ": scan " + sid() + " " + stage);
		json ev = {{"event", "progress"}, {"scan_id", sid()}, {"state", state_name(sm.state())},
			   {"message", text}};
		for (auto &c : clients)
			if (c->wait_scan == sid())
				send_line(*c, ev);
	}

	void send_line(Client &c, const json &j)
	{
		std::string s = j.dump() + "\n";
		// Replies are small; a client that does not read them is dropped, never waited for.
		ssize_t n = ::send(c.fd, s.data(), s.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
		if (n != static_cast<ssize_t>(s.size()))
			c.closing = true;
	}

	void reply_error(Client &c, const std::string &code, const std::string &message)
	{
		send_line(c, {{"ok", false}, {"error", code}, {"message", message}});
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

	void save_last()
	{
		Status s = write_file_atomic(spool.state_dir(), "last.json", last.dump(1) + "\n");
		if (!s.ok())
			log(LOG_WARNING, "cannot save the last scan's record: %s", s.message().c_str());
	}

	// The scan in flight, so that a daemon that dies mid-scan (crash, kill -9) reports it at
	// the next start instead of forgetting it.
	void save_current()
	{
		json rec = current;
		rec["state"] = state_name(sm.state());
		Status s = write_file_atomic(spool.state_dir(), "current.json", rec.dump(1) + "\n");
		if (!s.ok())
			log(LOG_WARNING, "cannot save the running scan's record: %s", s.message().c_str());
	}

	void load_last()
	{
		json j = read_small_json(spool.state_dir() + "/last.json");
		if (j.is_object())
			last = j;
	}

	// ---- socket ----------------------------------------------------------------------

	Status bind_socket()
	{
		const std::string &path = cfg.socket_path;
		struct sockaddr_un addr = {};
		addr.sun_family = AF_UNIX;
		if (path.size() >= sizeof addr.sun_path)
			return Status::error(ENAMETOOLONG, "socket path too long: " + path);
		std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
		int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
		if (fd < 0)
			return Status::error(errno, std::string("socket: ") + std::strerror(errno));
		// A socket file nobody answers on is left over from a crash; one that answers is a
		// running daemon, which we must not steal from.
		int probe = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
		if (probe >= 0) {
			if (connect(probe, reinterpret_cast<sockaddr *>(&addr), sizeof addr) == 0) {
				::close(probe);
				::close(fd);
				return Status::error(EADDRINUSE, path + ": another facescand is running");
			}
			::close(probe);
		}
		// We hold <socket>.lock, so a socket there is a dead daemon's; anything else is not
		// ours to delete.
		struct stat st;
		if (lstat(path.c_str(), &st) == 0) {
			if (!S_ISSOCK(st.st_mode)) {
				::close(fd);
				return Status::error(EEXIST, "socket_path " + path +
								     " exists and is not a socket; refusing to replace it");
			}
			unlink(path.c_str());
		}
		mode_t old = umask(0117);
		int r = bind(fd, reinterpret_cast<sockaddr *>(&addr), sizeof addr);
		int err = errno;
		umask(old);
		if (r < 0) {
			::close(fd);
			return Status::error(err, "bind " + path + ": " + std::strerror(err));
		}
		if (chmod(path.c_str(), 0660) < 0) {
			err = errno;
			::close(fd);
			return Status::error(err, "chmod " + path + ": " + std::strerror(err));
		}
		if (!cfg.socket_group.empty()) {
			// No chown when the socket has the group already (the shipped config names the
			// daemon's own group): the unit's SystemCallFilter then denies @chown too.
			struct group *g = getgrnam(cfg.socket_group.c_str());
			struct stat sst;
			if (!g || stat(path.c_str(), &sst) < 0 ||
			    (sst.st_gid != g->gr_gid && chown(path.c_str(), static_cast<uid_t>(-1), g->gr_gid) < 0)) {
				err = g ? errno : ENOENT;
				::close(fd);
				return Status::error(EPERM, "cannot give " + path + " to group " + cfg.socket_group + ": " +
								    (g ? std::strerror(err) : "no such group"));
			}
		}
		if (listen(fd, 16) < 0) {
			err = errno;
			::close(fd);
			return Status::error(err, std::string("listen: ") + std::strerror(err));
		}
		listen_fd = fd;
		return Status();
	}

	void accept_clients()
	{
		for (;;) {
			int fd = accept4(listen_fd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
			if (fd < 0)
				return;
			int open_clients = 0;
			for (const auto &c : clients)
				open_clients += !c->closing;
			if (open_clients >= kMaxClients) {
				// Full: the client that has waited longest without sending a request makes
				// room, so idle connections can never lock everyone out.
				Client *oldest = nullptr;
				for (auto &c : clients)
					if (c->wait_scan.empty() && !c->closing && (!oldest || c->deadline < oldest->deadline))
						oldest = c.get();
				if (oldest) {
					// Closed, not erased: run_once() maps its poll entries to clients by index.
					::shutdown(oldest->fd, SHUT_RDWR);
					oldest->closing = true;
					log_refusal("closed the longest-waiting idle client to admit a new one");
				} else {
					const char msg[] = "{\"ok\":false,\"error\":\"too_many_clients\",\"message\":"
							   "\"too many clients following scans\"}\n";
					if (::send(fd, msg, sizeof msg - 1, MSG_NOSIGNAL | MSG_DONTWAIT) < 0) {
						// the client is gone already
					}
					::close(fd);
					log_refusal("refused a client: all " + std::to_string(kMaxClients) +
						    " slots follow running scans");
					continue;
				}
			}
			auto c = std::make_unique<Client>();
			c->fd = fd;
			c->deadline = Clock::now() + std::chrono::milliseconds(cfg.client_timeout_ms);
			clients.push_back(std::move(c));
		}
	}

	// Refusals are logged, but a flood of them at most once a second (with the count).
	void log_refusal(const std::string &what)
	{
		auto now = Clock::now();
		if (now < next_refusal_log) {
			refusals_unlogged++;
			return;
		}
		if (refusals_unlogged)
			log(LOG_WARNING, "control: %s (and %ld more in the last second)", what.c_str(), refusals_unlogged);
		else
			log(LOG_WARNING, "control: %s", what.c_str());
		refusals_unlogged = 0;
		next_refusal_log = now + std::chrono::seconds(1);
	}

	void read_client(Client &c)
	{
		char buf[1024];
		for (;;) {
			ssize_t n = recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
			if (n == 0) {
				c.closing = true;
				break;
			}
			if (n < 0) {
				if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
					c.closing = true;
				break;
			}
			c.reader.feed(buf, static_cast<size_t>(n));
			std::string line;
			for (;;) {
				LineReader::Result r = c.reader.next(&line);
				if (r == LineReader::Result::need_more)
					break;
				if (r == LineReader::Result::too_large) {
					log(LOG_WARNING, "control: request larger than %zu bytes refused", kMaxRequest);
					reply_error(c, "too_large", "request larger than " + std::to_string(kMaxRequest) + " bytes");
					c.closing = true;
					return;
				}
				handle_line(c, line);
				c.deadline = Clock::now() + std::chrono::milliseconds(cfg.client_timeout_ms);
				if (c.closing)
					return;
			}
		}
	}

	void handle_line(Client &c, const std::string &line)
	{
		Request req;
		Status s = parse_request(line, &req);
		if (!s.ok()) {
			log(LOG_WARNING, "control: malformed request refused: %s", s.message().c_str());
			reply_error(c, "bad_request", s.message());
			c.closing = true;
			return;
		}
		switch (req.cmd) {
		case Request::Cmd::status:
			send_line(c, status_json());
			break;
		case Request::Cmd::last:
			if (last.is_null())
				send_line(c, {{"ok", true}, {"last", nullptr}});
			else
				send_line(c, {{"ok", true}, {"last", last}});
			break;
		case Request::Cmd::cancel:
			if (sm.state() != State::armed) {
				reply_error(c, "not_armed", std::string("nothing armed (state ") + state_name(sm.state()) + ")");
				break;
			}
			be.mcu->abort();
			transition(Event::disarm);
			progress("cancelled", "cancelled before the trigger");
			finish_record("cancelled", "");
			send_line(c, {{"ok", true}, {"state", state_name(sm.state())}});
			break;
		case Request::Cmd::button: {
			if (cfg.mode != Mode::booth) {
				// It would be ignored (on_button): say so instead of answering ok.
				reply_error(c, "unsupported", "the button starts scans only in booth mode (mode = clinic)");
				break;
			}
			Status b = be.mcu->simulate_button();
			if (!b.ok())
				reply_error(c, "unsupported", b.message());
			else
				send_line(c, {{"ok", true}});
			break;
		}
		case Request::Cmd::scan:
			handle_scan(c, req);
			break;
		}
	}

	void handle_scan(Client &c, const Request &req)
	{
		Status s = validate_patient_id(req.patient);
		if (!s.ok()) {
			log(LOG_WARNING, "control: scan refused: %s", s.message().c_str());
			reply_error(c, "bad_patient_id", s.message());
			return;
		}
		s = begin_scan(req.patient);
		if (!s.ok()) {
			reply_error(c, s.code() == -EBUSY ? "busy" : "unavailable", s.message());
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
		send_line(c, {{"ok", true}, {"scan_id", id}, {"state", state_name(sm.state())}});
		if (cfg.mode == Mode::clinic)
			fire();
	}

	// ---- scans -----------------------------------------------------------------------

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
		if (worker_running && worker_is_delivery)
			join_worker_if_done(true);
		Status s = sm.apply(Event::request);
		if (!s.ok()) {
			if (s.code() == -EAGAIN)
				return Status::error(EAGAIN, "unavailable: " + fault);
			if (sm.busy())
				return Status::error(EBUSY, "busy: scan " + sid() + " is " + state_name(sm.state()));
			return s;
		}
		set_state_pub();
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
		mcu_with_worker = true;
		start_worker(false);
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
		last = current;
		save_last();
		unlink((spool.state_dir() + "/current.json").c_str());
		json done = {{"event", "done"}, {"ok", outcome == "delivered" || outcome == "spooled"}, {"scan", last}};
		for (auto &c : clients)
			if (c->wait_scan == last.value("scan_id", "")) {
				send_line(*c, done);
				c->wait_scan.clear();
			}
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
		if (hardware) {
			be.mcu->abort();
		}
		next_recover = Clock::now();
	}

	// ---- worker ----------------------------------------------------------------------

	void start_worker(bool delivery_only)
	{
		worker_running = true;
		worker_is_delivery = delivery_only;
		json rec = current;
		if (delivery_only)
			worker = std::thread([this] { deliver_job(); });
		else
			worker = std::thread([this, rec] { scan_job(rec); });
	}

	void join_worker_if_done(bool wait)
	{
		if (!worker_running)
			return;
		if (!wait)
			return;
		worker.join();
		worker_running = false;
	}

	void deliver_job()
	{
		std::vector<Delivered> out;
		Status s = spool.deliver(&out, cfg.test_delay_deliver_ms);
		clinic::retry_pacs(cfg); // after the share: a late send can then record itself in the metadata
		Msg m{Msg::Kind::delivered, 0, "", false, json::array()};
		m.data = json::array();
		for (const Delivered &d : out)
			m.data.push_back({{"scan_id", d.scan_id}, {"paths", d.paths}});
		if (!s.ok())
			m.text = s.message();
		post(std::move(m));
	}

	void scan_job(json rec)
	{
		const std::string id = rec["scan_id"];
		// capture
		auto t0 = Clock::now();
		Capture cap;
		Status s = be.cameras->prepare_at_arm() ? Status() : be.cameras->prepare();
		if (!s.ok()) {
			post({Msg::Kind::failed, 0, "cameras: " + s.message(), true, {{"stage", "capturing"}}});
			return;
		}
		TriggerReport report;
		s = be.mcu->fire(cfg.mcu_timeout_ms, &report);
		if (!s.ok()) {
			post({Msg::Kind::failed, 0, s.message(), true, {{"stage", "capturing"}}});
			return;
		}
		s = be.cameras->collect(report, cfg.capture_timeout_ms, &cap);
		if (s.ok())
			s = check_capture(cap, be.cameras->count(), cfg.max_frame_skew_us);
		if (!s.ok()) {
			post({Msg::Kind::failed, 0, "cameras: " + s.message(), true, {{"stage", "capturing"}}});
			return;
		}
		cap.report = report;
		cap.scan_name = rec["base"];
		double capture_ms = ms_since(t0);
		post({Msg::Kind::captured, capture_ms,
		      "[1/3] captured " + std::to_string(cap.frames.size()) + " frames of trigger " +
			      std::to_string(report.sequence) + " in " + std::to_string(static_cast<long>(capture_ms)) + " ms",
		      false, {{"trigger_report", report.raw}}});

		// reconstruction
		auto t1 = Clock::now();
		ReconOutput out;
		s = be.recon->run(cap, &out);
		if (!s.ok()) {
			post({Msg::Kind::failed, 0, "reconstruction: " + s.message(), false, {{"stage", "reconstructing"}}});
			return;
		}
		double recon_ms = ms_since(t1);
		// The worker backend keeps a whole set itself (keep_captures); others get the frames.
		if (cfg.keep_captures &&
		    access((cfg.spool_dir + "/captures/" + rec["base"].get<std::string>() + "/calibration.yaml").c_str(), F_OK) != 0)
			keep_capture(rec["base"], cap);
		json recon_stages = json::object();
		for (const auto &st : out.stage_ms)
			recon_stages[st.first] = st.second;
		post({Msg::Kind::reconstructed, recon_ms,
		      "[2/3] reconstructed " + std::to_string(out.vertices) + " vertices in " +
			      std::to_string(static_cast<long>(recon_ms)) + " ms",
		      false,
		      {{"vertices", out.vertices},
		       {"faces", out.faces},
		       {"recon_stage_ms", recon_stages},
		       {"warnings", out.quality.is_object() ? out.quality.value("warnings", json::array()) : json::array()}}});

		// writing: spool (the commit point), then the share
		auto t2 = Clock::now();
		const std::string base = rec["base"];
		json meta = {{"scan_id", id},
			     {"patient_id", rec["patient_id"]},
			     {"started_utc", rec["started_utc"]},
			     {"software_version", version()},
			     {"mode", mode_name(cfg.mode)},
			     {"stage_ms", {{"capture", capture_ms}, {"reconstruct", recon_ms}}},
			     {"recon_stage_ms", recon_stages},
			     {"trigger_report", report.raw},
			     {"firmware", be.mcu->firmware_version()},
			     {"calibration_id", cap.calibration_id},
			     {"camera_backend", be.cameras->backend_name()},
			     {"cameras", cap.meta},
			     {"recon_backend", be.recon->backend_name()},
			     {"vertices", out.vertices},
			     {"faces", out.faces},
			     {"quality", out.quality},
			     {"files", {{"mesh", base + ".drc"}, {"texture", base + ".png"}}}};
		std::vector<SpoolFile> files = {{base + ".drc", out.drc}, {base + ".png", out.png}};
		clinic::add_outputs(cfg, out, rec, &files, &meta); // .glb, thumbnail, .stl/.obj, DICOM, manifest
		files.push_back({base + ".json", meta.dump(1) + "\n"});
		s = spool.put(base, id, rec["patient_id"], files, cfg.test_delay_write_ms);
		if (!s.ok()) {
			post({Msg::Kind::failed, 0, "spool: " + s.message() + capture_kept(base), false,
			      {{"stage", "writing"}}});
			return;
		}
		be.recon->release(base);
		std::vector<Delivered> delivered;
		Status d = spool.deliver(&delivered, cfg.test_delay_deliver_ms);
		bool landed = false;
		json paths = json::array();
		for (const Delivered &x : delivered)
			if (x.scan_id == id) {
				landed = true;
				paths = x.paths;
			}
		json data = {{"write_ms", ms_since(t2)}, {"outcome", landed ? "delivered" : "spooled"}, {"files", paths}};
		if (!landed)
			data["spool_reason"] = d.ok() ? "an older spooled scan is ahead" : d.message();
		post({Msg::Kind::finished, ms_since(t2), "", false, data});
	}

	// "; capture kept in DIR" when a capture set of the scan is in <spool_dir>/captures, else "".
	std::string capture_kept(const std::string &base) const
	{
		const std::string dir = cfg.spool_dir + "/captures/" + base;
		struct stat st;
		if (base.empty() || stat(dir.c_str(), &st) < 0 || !S_ISDIR(st.st_mode))
			return "";
		return "; capture kept in " + dir + " for an offline retry";
	}

	void keep_capture(const std::string &base, const Capture &cap)
	{
		const std::string dir = cfg.spool_dir + "/captures";
		mkdir(dir.c_str(), 0750);
		const std::string set = dir + "/" + base;
		if (mkdir(set.c_str(), 0750) < 0 && errno != EEXIST)
			return;
		for (const Frame &f : cap.frames)
			cv::imwrite(set + "/cam" + std::to_string(f.camera) + (f.texture ? "_texture" : "") + ".png", f.image);
		json meta = {{"scan_id", base.substr(base.rfind('_') + 1)}, {"trigger_report", cap.report.raw}};
		write_file_atomic(set, "capture.json", meta.dump(1) + "\n");
	}

	void drain_messages()
	{
		uint64_t n;
		if (read(wake_fd, &n, sizeof n) < 0) {
			// EAGAIN: nothing new
		}
		std::deque<Msg> batch;
		{
			std::lock_guard<std::mutex> lock(msg_mu);
			batch.swap(msgs);
		}
		for (Msg &m : batch)
			handle_msg(m);
	}

	void handle_msg(Msg &m)
	{
		switch (m.kind) {
		case Msg::Kind::captured:
			mcu_with_worker = false;
			transition(Event::captured);
			stage_start = Clock::now();
			current["stage_ms"]["capture"] = m.ms;
			current["trigger_report"] = m.data["trigger_report"];
			current["state"] = "reconstructing";
			progress("reconstructing", m.text + "; [2/3] reconstructing");
			break;
		case Msg::Kind::reconstructed:
			transition(Event::reconstructed);
			stage_start = Clock::now();
			current["stage_ms"]["reconstruct"] = m.ms;
			current["vertices"] = m.data["vertices"];
			current["faces"] = m.data["faces"];
			current["recon_stage_ms"] = m.data["recon_stage_ms"];
			// A suspect scan (wrong pattern, a camera that adds nothing) is said where the
			// operator looks: the log and `facescan last`, not only the metadata.
			if (m.data["warnings"].is_array() && !m.data["warnings"].empty()) {
				current["warnings"] = m.data["warnings"];
				for (const auto &w : m.data["warnings"])
					if (w.is_string())
						log(LOG_WARNING, "scan %s: %s", sid().c_str(), w.get<std::string>().c_str());
			}
			current["state"] = "writing";
			progress("writing", m.text + "; [3/3] writing");
			break;
		case Msg::Kind::finished: {
			join_worker_if_done(true);
			transition(Event::written);
			current["stage_ms"]["write"] = m.data["write_ms"];
			current["files"] = m.data["files"];
			const std::string outcome = m.data["outcome"];
			double total = 0;
			for (auto &v : current["stage_ms"])
				total += v.get<double>();
			if (outcome == "delivered") {
				log(LOG_INFO, "scan %s: [3/3] delivered to the share in %ld ms (total %ld ms)",
				    sid().c_str(), static_cast<long>(m.ms), static_cast<long>(total));
			} else {
				current["spool_reason"] = m.data["spool_reason"];
				log(LOG_WARNING, "scan %s: [3/3] spooled, the share cannot take it yet (%s); total %ld ms",
				    sid().c_str(), m.data.value("spool_reason", "").c_str(), static_cast<long>(total));
				next_delivery = Clock::now() + std::chrono::milliseconds(cfg.spool_retry_ms);
			}
			notify("STATUS=idle: last scan " + sid() + " " + outcome);
			finish_record(outcome, "");
			break;
		}
		case Msg::Kind::failed:
			join_worker_if_done(true);
			mcu_with_worker = false;
			fail_scan(m.data.value("stage", "?"), m.text, m.hardware);
			try_recover();
			break;
		case Msg::Kind::delivered:
			// A scan may have started after joining this job already (begin_scan).
			if (worker_is_delivery)
				join_worker_if_done(true);
			for (const auto &d : m.data) {
				const std::string id = d["scan_id"];
				log(LOG_INFO, "scan %s: spooled scan delivered to the share", id.c_str());
				if (last.value("scan_id", "") == id) {
					last["state"] = "delivered";
					last["files"] = d["paths"];
					last.erase("spool_reason");
					save_last();
				}
			}
			if (!m.text.empty())
				next_delivery = Clock::now() + std::chrono::milliseconds(cfg.spool_retry_ms);
			break;
		}
	}

	// ---- recovery and timers ----------------------------------------------------------

	void try_recover()
	{
		if (sm.state() != State::error || worker_running)
			return;
		next_recover = Clock::now() + std::chrono::milliseconds(kRecoverEveryMs);
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

	void poll_mcu()
	{
		if (mcu_with_worker || sm.state() == State::error)
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

	void timers()
	{
		auto now = Clock::now();
		if (sm.state() == State::armed && now >= arm_deadline) {
			be.mcu->abort();
			transition(Event::disarm);
			log(LOG_INFO, "scan %s: no button press within %d ms, disarmed", sid().c_str(), cfg.arm_timeout_ms);
			finish_record("cancelled", "no button press in time");
		}
		if (sm.state() == State::error && now >= next_recover)
			try_recover();
		if (!sm.busy() && !worker_running && now >= next_delivery &&
		    (spool.pending() > 0 || clinic::pacs_pending(cfg))) {
			next_delivery = now + std::chrono::milliseconds(cfg.spool_retry_ms);
			start_worker(true);
		}
		if (!mcu_with_worker && now >= next_mcu_poll) {
			next_mcu_poll = now + std::chrono::milliseconds(kMcuPollMs);
			poll_mcu();
		}
		if (watchdog_usec && now >= next_ping) {
			next_ping = now + std::chrono::microseconds(watchdog_usec / 2);
			// A stage that overruns means a hung worker: stop pinging and let systemd restart us.
			if (!sm.busy() || ms_since(stage_start) < cfg.stage_timeout_ms)
				notify("WATCHDOG=1");
			else
				log(LOG_CRIT, "scan %s: stage %s overran %d ms, watchdog pings stopped", sid().c_str(),
				    state_name(sm.state()), cfg.stage_timeout_ms);
		}
		for (auto &c : clients)
			if (c->wait_scan.empty() && !c->closing && now >= c->deadline) {
				c->closing = true;
				log_refusal("closed a client that sent no whole request within " +
					    std::to_string(cfg.client_timeout_ms) + " ms");
			}
	}

	int next_timeout() const
	{
		auto now = Clock::now();
		auto soonest = now + std::chrono::milliseconds(1000);
		auto consider = [&](Clock::time_point t) {
			if (t < soonest)
				soonest = t;
		};
		if (sm.state() == State::armed)
			consider(arm_deadline);
		if (sm.state() == State::error)
			consider(next_recover);
		if (!sm.busy() && !worker_running && spool.pending() > 0)
			consider(next_delivery);
		if (!mcu_with_worker && be.mcu->event_fd() < 0)
			consider(next_mcu_poll);
		if (watchdog_usec)
			consider(next_ping);
		for (const auto &c : clients)
			if (c->wait_scan.empty())
				consider(c->deadline);
		return ms_until(soonest);
	}

	Status run_once()
	{
		std::vector<pollfd> fds;
		fds.push_back({wake_fd, POLLIN, 0});
		fds.push_back({listen_fd, POLLIN, 0});
		int mcu_fd = mcu_with_worker ? -1 : be.mcu->event_fd();
		fds.push_back({mcu_fd, POLLIN, 0});
		for (auto &c : clients)
			fds.push_back({c->fd, POLLIN, 0});
		int r = poll(fds.data(), fds.size(), next_timeout());
		if (r < 0 && errno != EINTR)
			return Status::error(errno, std::string("poll: ") + std::strerror(errno));
		if (r > 0) {
			if (fds[0].revents)
				drain_messages();
			if (fds[2].revents)
				next_mcu_poll = Clock::now();
			if (fds[1].revents)
				accept_clients();
			for (size_t i = 3; i < fds.size() && i - 3 < clients.size(); i++)
				if (fds[i].revents && !clients[i - 3]->closing)
					read_client(*clients[i - 3]);
		}
		timers();
		for (auto it = clients.begin(); it != clients.end();) {
			if ((*it)->closing) {
				::close((*it)->fd);
				it = clients.erase(it);
			} else {
				++it;
			}
		}
		return Status();
	}
};

Daemon::Daemon(Config config, Backends backends) : impl_(std::make_unique<Impl>(std::move(config), std::move(backends)))
{
}

Daemon::~Daemon()
{
	Impl &d = *impl_;
	if (d.worker_running)
		d.worker.join();
	for (auto &c : d.clients)
		::close(c->fd);
	if (d.listen_fd >= 0) {
		::close(d.listen_fd);
		unlink(d.cfg.socket_path.c_str());
	}
	if (d.wake_fd >= 0)
		::close(d.wake_fd);
	if (d.socket_lock_fd >= 0)
		::close(d.socket_lock_fd);
	if (d.lock_fd >= 0)
		::close(d.lock_fd);
	if (d.be.mcu)
		d.be.mcu->close();
}

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
	uint64_t one = 1;
	if (impl_->wake_fd >= 0 && write(impl_->wake_fd, &one, sizeof one) < 0) {
		// saturated: a wake-up is pending
	}
}

Status Daemon::start()
{
	Impl &d = *impl_;
	if (!d.be.mcu || !d.be.cameras || !d.be.recon)
		return Status::error(EINVAL, "facescand: a backend is missing");
	d.wake_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
	if (d.wake_fd < 0)
		return Status::error(errno, std::string("eventfd: ") + std::strerror(errno));
	// One daemon per spool and per socket, settled before anything is touched: a second
	// daemon must not run crash recovery on a live daemon's spool.
	Status s = d.spool.init();
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
	s = d.bind_socket();
	if (!s.ok())
		return s;
	d.load_last();
	std::vector<std::string> failed;
	s = d.spool.recover(&failed);
	if (!s.ok())
		return s;
	{
		// The scan the previous daemon did not finish. The spool decides what became of it:
		// queued (delivered next), on the share already, or lost before it was spooled.
		json cur = read_small_json(d.spool.state_dir() + "/current.json");
		if (cur.is_object() && cur.contains("scan_id")) {
			const std::string st = cur.value("state", "?");
			const std::string id = cur.value("scan_id", "");
			const std::string base = cur.value("base", "");
			const bool on_share = !base.empty() &&
					      access((d.cfg.share_dir + "/" + cur.value("patient_id", "") + "/" +
						      base + ".json").c_str(), F_OK) == 0;
			cur.erase("base");
			if (d.spool.queued(id)) {
				log(LOG_WARNING, "scan %s: the daemon stopped before delivering it; delivering it from the spool",
				    id.c_str());
				cur["state"] = "spooled";
				cur["spool_reason"] = "the daemon stopped while delivering it";
			} else if (st == "writing" && on_share &&
				   std::find(failed.begin(), failed.end(), id) == failed.end()) {
				log(LOG_INFO, "scan %s: delivered before the daemon stopped", id.c_str());
				cur["state"] = "delivered";
			} else {
				const std::string kept = d.capture_kept(base);
				log(LOG_ERR, "scan %s: interrupted while %s (daemon stopped); reported failed%s", id.c_str(),
				    st.c_str(), kept.c_str());
				cur["state"] = "failed";
				cur["failed_stage"] = st;
				cur["error"] = "interrupted while " + st + ": the daemon stopped; scan again" + kept;
			}
			failed.erase(std::remove(failed.begin(), failed.end(), id), failed.end());
			d.last = cur;
			d.save_last();
		}
		unlink((d.spool.state_dir() + "/current.json").c_str());
	}
	for (const std::string &id : failed) {
		log(LOG_ERR, "scan %s: interrupted while writing (daemon stopped); reported failed", id.c_str());
		if (d.last.value("scan_id", "") != id || d.last.value("state", "") != "failed") {
			d.last = {{"scan_id", id},
				  {"state", "failed"},
				  {"failed_stage", "writing"},
				  {"error", "interrupted while writing: the daemon stopped; scan again"}};
			d.save_last();
		}
	}
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
	d.set_state_pub();
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
	if (d.worker_running) {
		log(LOG_INFO, "stopping: waiting for the running stage to finish");
		// Let the worker finish and record its outcome so nothing is left half-written.
		while (d.worker_running) {
			pollfd p = {d.wake_fd, POLLIN, 0};
			poll(&p, 1, 1000);
			d.drain_messages();
		}
	}
	log(LOG_INFO, "stopped");
	return Status();
}

} // namespace facescan::daemon
