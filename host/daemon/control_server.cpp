#include "daemon/control_server.hpp"

#include "daemon/clock.hpp"
#include "daemon/log.hpp"

#include <cerrno>
#include <cstring>
#include <grp.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

namespace facescan::daemon {

using json = nlohmann::json;

namespace {
constexpr int kMaxClients = 32;
}

void ControlServer::shutdown()
{
	for (auto &c : clients_)
		::close(c->fd);
	clients_.clear();
	if (listen_fd_ >= 0) {
		::close(listen_fd_);
		unlink(cfg_.socket_path.c_str());
		listen_fd_ = -1;
	}
}

Status ControlServer::bind()
{
	const std::string &path = cfg_.socket_path;
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
	int r = ::bind(fd, reinterpret_cast<sockaddr *>(&addr), sizeof addr);
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
	if (!cfg_.socket_group.empty()) {
		// No chown when the socket has the group already (the shipped config names the
		// daemon's own group): the unit's SystemCallFilter then denies @chown too.
		struct group *g = getgrnam(cfg_.socket_group.c_str());
		struct stat sst;
		if (!g || stat(path.c_str(), &sst) < 0 ||
		    (sst.st_gid != g->gr_gid && chown(path.c_str(), static_cast<uid_t>(-1), g->gr_gid) < 0)) {
			err = g ? errno : ENOENT;
			::close(fd);
			return Status::error(EPERM, "cannot give " + path + " to group " + cfg_.socket_group + ": " +
							    (g ? std::strerror(err) : "no such group"));
		}
	}
	if (listen(fd, 16) < 0) {
		err = errno;
		::close(fd);
		return Status::error(err, std::string("listen: ") + std::strerror(err));
	}
	listen_fd_ = fd;
	return Status();
}

void ControlServer::accept_clients()
{
	for (;;) {
		int fd = accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
		if (fd < 0)
			return;
		int open_clients = 0;
		for (const auto &c : clients_)
			open_clients += !c->closing;
		if (open_clients >= kMaxClients) {
			// Full: the client that has waited longest without sending a request makes
			// room, so idle connections can never lock everyone out.
			Client *oldest = nullptr;
			for (auto &c : clients_)
				if (c->wait_scan.empty() && !c->closing && (!oldest || c->deadline < oldest->deadline))
					oldest = c.get();
			if (oldest) {
				// Closed, not erased: the loop maps its poll entries to clients_ by index.
				::shutdown(oldest->fd, SHUT_RDWR);
				oldest->closing = true;
				log_refusal("closed the longest-waiting idle client to admit a new one");
			} else {
				const char msg[] = "{\"ok\":false,\"error\":\"too_many_clients\",\"message\":"
						   "\"too many clients_ following scans\"}\n";
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
		c->deadline = Clock::now() + std::chrono::milliseconds(cfg_.client_timeout_ms);
		clients_.push_back(std::move(c));
	}
}

// Refusals are logged, but a flood of them at most once a second (with the count).
void ControlServer::log_refusal(const std::string &what)
{
	auto now = Clock::now();
	if (now < next_refusal_log_) {
		refusals_unlogged_++;
		return;
	}
	if (refusals_unlogged_)
		log(LOG_WARNING, "control: %s (and %ld more in the last second)", what.c_str(), refusals_unlogged_);
	else
		log(LOG_WARNING, "control: %s", what.c_str());
	refusals_unlogged_ = 0;
	next_refusal_log_ = now + std::chrono::seconds(1);
}

void ControlServer::read_client(size_t i)
{
	Client &c = *clients_[i];
	if (c.closing)
		return;
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
			c.deadline = Clock::now() + std::chrono::milliseconds(cfg_.client_timeout_ms);
			if (c.closing)
				return;
		}
	}
}

void ControlServer::handle_line(Client &c, const std::string &line)
{
	Request req;
	Status s = parse_request(line, &req);
	if (!s.ok()) {
		log(LOG_WARNING, "control: malformed request refused: %s", s.message().c_str());
		reply_error(c, "bad_request", s.message());
		c.closing = true;
		return;
	}
	handler_(c, req);
}

std::optional<Clock::time_point> ControlServer::next_deadline() const
{
	std::optional<Clock::time_point> soonest;
	for (const auto &c : clients_)
		if (c->wait_scan.empty() && !c->closing && (!soonest || c->deadline < *soonest))
			soonest = c->deadline;
	return soonest;
}

void ControlServer::expire_clients()
{
	auto now = Clock::now();
	for (auto &c : clients_)
		if (c->wait_scan.empty() && !c->closing && now >= c->deadline) {
			c->closing = true;
			log_refusal("closed a client that sent no whole request within " +
				    std::to_string(cfg_.client_timeout_ms) + " ms");
		}
}

void ControlServer::close_finished()
{
	for (auto it = clients_.begin(); it != clients_.end();) {
		if ((*it)->closing) {
			::close((*it)->fd);
			it = clients_.erase(it);
		} else {
			++it;
		}
	}
}

void ControlServer::send(Client &c, const json &j)
{
	std::string s = j.dump() + "\n";
	// Replies are small; a client that does not read them is dropped, never waited for.
	ssize_t n = ::send(c.fd, s.data(), s.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
	if (n != static_cast<ssize_t>(s.size()))
		c.closing = true;
}

void ControlServer::reply_error(Client &c, const std::string &code, const std::string &message)
{
	send(c, {{"ok", false}, {"error", code}, {"message", message}});
}

void ControlServer::tell_followers(const std::string &scan_id, const json &ev, bool last)
{
	for (auto &c : clients_)
		if (!scan_id.empty() && c->wait_scan == scan_id) {
			send(*c, ev);
			if (last)
				c->wait_scan.clear();
		}
}

} // namespace facescan::daemon
