// The control socket's server side (the protocol is control.hpp): the listening socket, the
// connected clients, their line framing and replies, and the defences of a socket anyone in
// the group may open: a whole request must arrive within client_timeout_ms (slowloris), at most
// kMaxClients are connected (the longest-idle one makes room), and refusals are logged at most
// once a second. It decides nothing about scans: each well-formed request goes to the handler.
#pragma once

#include "common/status.hpp"
#include "daemon/clock.hpp"
#include "daemon/config.hpp"
#include "daemon/control.hpp"

#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace facescan::daemon {

struct Client {
	int fd = -1;
	LineReader reader;
	std::string wait_scan;  // scan id whose progress this client follows
	// A whole request must arrive by then, however slowly its bytes trickle in (slowloris);
	// renewed after each request. A client following a scan is exempt.
	Clock::time_point deadline;
	bool closing = false;
};

class ControlServer {
public:
	using Handler = std::function<void(Client &, const Request &)>;

	ControlServer(const Config &cfg, Handler handler) : cfg_(cfg), handler_(std::move(handler))
	{
	}
	~ControlServer()
	{
		shutdown();
	}
	ControlServer(const ControlServer &) = delete;
	ControlServer &operator=(const ControlServer &) = delete;

	/// Binds cfg.socket_path (0660, cfg.socket_group) after checking that no live daemon answers
	/// there. -EADDRINUSE a daemon answers, -EEXIST not a socket, -EPERM the group, or the call's.
	Status bind();
	/// Closes every client and the socket, and removes the socket file if bound. The daemon
	/// calls it before it lets go of <socket>.lock: a successor may bind only then.
	void shutdown();
	int listen_fd() const
	{
		return listen_fd_;
	}
	/// The clients, in the order of their poll entries.
	const std::vector<std::unique_ptr<Client>> &clients() const
	{
		return clients_;
	}

	/// The listening socket is readable.
	void accept_clients();
	/// Client `i` is readable: reads, and hands each whole request to the handler.
	void read_client(size_t i);
	/// The soonest deadline of a client that owes us a request, if any.
	std::optional<Clock::time_point> next_deadline() const;
	/// Closes the clients whose deadline passed.
	void expire_clients();
	/// Drops the clients marked closing (after the poll entries are no longer used).
	void close_finished();

	void send(Client &c, const nlohmann::json &j);
	void reply_error(Client &c, const std::string &code, const std::string &message);
	/// Sends `ev` to every client following `scan_id`; `last` ends their following.
	void tell_followers(const std::string &scan_id, const nlohmann::json &ev, bool last);

private:
	void handle_line(Client &c, const std::string &line);
	void log_refusal(const std::string &what);

	const Config &cfg_;
	Handler handler_;
	int listen_fd_ = -1;
	std::vector<std::unique_ptr<Client>> clients_;
	Clock::time_point next_refusal_log_;
	long refusals_unlogged_ = 0;
};

} // namespace facescan::daemon
