// facescand speaks systemd's notify protocol (Type=notify, WatchdogSec): run the real binary
// with NOTIFY_SOCKET and WATCHDOG_USEC pointing at us, and read its datagrams.
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <poll.h>
#include <string>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

// cmocka last: its macros (fail, ...) clash with the standard library
#include <cstdarg>
#include <cstddef>
#include <setjmp.h>
extern "C" {
#include <cmocka.h>
}

static std::vector<std::string> read_for(int fd, int ms, const char *until)
{
	std::vector<std::string> got;
	auto end = std::chrono::steady_clock::now() + std::chrono::milliseconds(ms);
	while (std::chrono::steady_clock::now() < end) {
		pollfd p = {fd, POLLIN, 0};
		if (poll(&p, 1, 50) <= 0)
			continue;
		char buf[512];
		ssize_t n = recv(fd, buf, sizeof buf - 1, 0);
		if (n <= 0)
			continue;
		buf[n] = 0;
		got.emplace_back(buf);
		if (until && std::strstr(buf, until))
			break;
	}
	return got;
}

static bool has(const std::vector<std::string> &v, const char *s)
{
	for (const std::string &x : v)
		if (x.find(s) != std::string::npos)
			return true;
	return false;
}

static void test_ready_watchdog_stopping(void **)
{
	const char *bin = std::getenv("FACESCAN_BIN");
	if (!bin)
		bin = "build/asan/bin";
	char dir[] = "/tmp/facescan-notify-XXXXXX";
	assert_non_null(mkdtemp(dir));
	const std::string d = dir, sock = d + "/notify", conf = d + "/facescand.conf";
	mkdir((d + "/share").c_str(), 0755);
	std::ofstream(conf) << "share_dir = " << d << "/share\nspool_dir = " << d << "/spool\nsocket_path = " << d
			    << "/ctl\nserial_device = fake\ncamera_backend = fake\nrecon_backend = fake\n";
	int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
	assert_true(fd >= 0);
	sockaddr_un addr = {};
	addr.sun_family = AF_UNIX;
	std::strcpy(addr.sun_path, sock.c_str());
	assert_int_equal(bind(fd, reinterpret_cast<sockaddr *>(&addr), sizeof addr), 0);
	pid_t pid = fork();
	if (pid == 0) {
		setenv("NOTIFY_SOCKET", sock.c_str(), 1);
		setenv("WATCHDOG_USEC", "400000", 1);
		setenv("WATCHDOG_PID", std::to_string(getpid()).c_str(), 1);
		std::string exe = std::string(bin) + "/facescand";
		execl(exe.c_str(), exe.c_str(), "--config", conf.c_str(), static_cast<char *>(nullptr));
		_exit(127);
	}
	std::vector<std::string> got = read_for(fd, 10000, "READY=1");
	assert_true(has(got, "READY=1"));
	// pings every WATCHDOG_USEC/2 = 200 ms: at least 3 in a second
	std::vector<std::string> later = read_for(fd, 1000, nullptr);
	int pings = 0;
	for (const std::string &m : later)
		pings += m.find("WATCHDOG=1") != std::string::npos;
	std::printf("watchdog pings in 1 s: %d\n", pings);
	assert_true(pings >= 3);
	kill(pid, SIGTERM);
	std::vector<std::string> bye = read_for(fd, 5000, "STOPPING=1");
	assert_true(has(bye, "STOPPING=1"));
	int status = 0;
	waitpid(pid, &status, 0);
	assert_true(WIFEXITED(status));
	assert_int_equal(WEXITSTATUS(status), 0);
	close(fd);
	std::string rm = "rm -rf '" + d + "'";
	assert_int_equal(std::system(rm.c_str()), 0);
}

int main()
{
	const struct CMUnitTest tests[] = {cmocka_unit_test(test_ready_watchdog_stopping)};
	return cmocka_run_group_tests(tests, nullptr, nullptr);
}
