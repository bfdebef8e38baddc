#include "daemon/client.hpp"

#include "daemon/config.hpp"

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

namespace facescan::daemon {

std::string default_socket_path()
{
	const char *env = std::getenv("FACESCAN_SOCKET");
	return env && *env ? env : Config{}.socket_path;
}

namespace {

class Conn {
public:
	~Conn()
	{
		if (fd >= 0)
			::close(fd);
	}
	int fd = -1;
};

Status connect_to(const std::string &path, Conn *c)
{
	struct sockaddr_un addr = {};
	addr.sun_family = AF_UNIX;
	if (path.size() >= sizeof addr.sun_path)
		return Status::error(ENAMETOOLONG, "socket path too long: " + path);
	std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
	c->fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
	if (c->fd < 0)
		return Status::error(errno, std::string("socket: ") + std::strerror(errno));
	if (connect(c->fd, reinterpret_cast<sockaddr *>(&addr), sizeof addr) < 0) {
		int err = errno;
		return Status::error(err, "cannot reach facescand at " + path + ": " + std::strerror(err));
	}
	return Status();
}

Status send_all(int fd, const std::string &s)
{
	size_t off = 0;
	while (off < s.size()) {
		ssize_t n = ::send(fd, s.data() + off, s.size() - off, MSG_NOSIGNAL);
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0)
			return Status::error(errno, std::string("send: ") + std::strerror(errno));
		off += static_cast<size_t>(n);
	}
	return Status();
}

// Reads one line; "" with ok status at EOF.
Status read_line(int fd, std::string *buf, std::string *ret_line, bool *ret_eof, int timeout_ms)
{
	*ret_eof = false;
	for (;;) {
		size_t nl = buf->find('\n');
		if (nl != std::string::npos) {
			ret_line->assign(*buf, 0, nl);
			buf->erase(0, nl + 1);
			return Status();
		}
		pollfd p = {fd, POLLIN, 0};
		int r = poll(&p, 1, timeout_ms);
		if (r < 0 && errno == EINTR)
			continue;
		if (r == 0)
			return Status::error(ETIMEDOUT, "facescand did not answer within " + std::to_string(timeout_ms) + " ms");
		char tmp[4096];
		ssize_t n = recv(fd, tmp, sizeof tmp, 0);
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0 && errno == ECONNRESET)
			n = 0;
		if (n < 0)
			return Status::error(errno, std::string("recv: ") + std::strerror(errno));
		if (n == 0) {
			*ret_eof = true;
			ret_line->clear();
			return Status();
		}
		buf->append(tmp, static_cast<size_t>(n));
	}
}

} // namespace

Status control_request(const std::string &socket_path, const nlohmann::json &request,
		       const std::function<bool(const nlohmann::json &)> &on_reply, int timeout_ms)
{
	Conn c;
	Status s = connect_to(socket_path, &c);
	if (!s.ok())
		return s;
	s = send_all(c.fd, request.dump() + "\n");
	if (!s.ok())
		return s;
	std::string buf, line;
	for (;;) {
		bool eof;
		s = read_line(c.fd, &buf, &line, &eof, timeout_ms);
		if (!s.ok())
			return s;
		if (eof)
			return Status::error(EPIPE, "facescand closed the connection");
		nlohmann::json j = nlohmann::json::parse(line, nullptr, false);
		if (j.is_discarded())
			return Status::error(EPROTO, "facescand sent a reply that is not JSON");
		if (!on_reply(j))
			return Status();
	}
}

Status control_raw(const std::string &socket_path, const std::string &bytes, std::string *ret_reply, int timeout_ms)
{
	Conn c;
	Status s = connect_to(socket_path, &c);
	if (!s.ok())
		return s;
	s = send_all(c.fd, bytes);
	if (!s.ok() && s.code() != -EPIPE && s.code() != -ECONNRESET)
		return s;
	std::string buf;
	bool eof;
	return read_line(c.fd, &buf, ret_reply, &eof, timeout_ms);
}

} // namespace facescan::daemon
