/* Real serial transport: a tty in raw mode (termios), non-blocking, with poll() for timeouts.
 * A USB serial adapter that is unplugged (or a pty whose master closes) shows up as POLLHUP,
 * read() returning 0, or EIO/ENXIO/ENODEV: all reported as -ENOTCONN. */
#define _GNU_SOURCE
#include "serial_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <stdlib.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

struct tty {
	int fd;
};

static int baud_to_speed(unsigned baud, speed_t *ret)
{
	static const struct {
		unsigned baud;
		speed_t speed;
	} table[] = {
		{9600, B9600}, {19200, B19200}, {38400, B38400}, {57600, B57600}, {115200, B115200},
		{230400, B230400}, {460800, B460800}, {500000, B500000}, {576000, B576000},
		{921600, B921600}, {1000000, B1000000}, {1152000, B1152000}, {1500000, B1500000},
		{2000000, B2000000}, {2500000, B2500000}, {3000000, B3000000}, {3500000, B3500000},
		{4000000, B4000000},
	};
	for (size_t i = 0; i < sizeof(table) / sizeof(table[0]); i++)
		if (table[i].baud == baud) {
			*ret = table[i].speed;
			return 0;
		}
	return -EINVAL;
}

static bool is_hangup(int err)
{
	return err == EIO || err == ENXIO || err == ENODEV || err == EPIPE;
}

static int tty_open(const struct fscan_serial_config *cfg, void **ret_ctx)
{
	speed_t speed;
	int r = baud_to_speed(cfg->baud ? cfg->baud : 115200, &speed);
	if (r < 0)
		return r;
	struct tty *t = calloc(1, sizeof(*t));
	if (!t)
		return -ENOMEM;
	t->fd = open(cfg->device, O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
	if (t->fd < 0) {
		r = -errno;
		goto err_free;
	}
	if (!isatty(t->fd)) {
		r = -ENOTTY;
		goto err_close;
	}
	struct termios tio;
	if (tcgetattr(t->fd, &tio) < 0) {
		r = -errno;
		goto err_close;
	}
	/* Raw 8N1: no line discipline, no echo, no translation, no flow control; reads return what
	 * is there (VMIN = VTIME = 0, the waiting is poll()'s). */
	cfmakeraw(&tio);
	tio.c_cflag &= ~(tcflag_t)(CSTOPB | PARENB | CRTSCTS | CSIZE);
	tio.c_cflag |= CS8 | CLOCAL | CREAD;
	tio.c_iflag &= ~(tcflag_t)(IXON | IXOFF | IXANY);
	tio.c_cc[VMIN] = 0;
	tio.c_cc[VTIME] = 0;
	if (cfsetispeed(&tio, speed) < 0 || cfsetospeed(&tio, speed) < 0 || tcsetattr(t->fd, TCSANOW, &tio) < 0) {
		r = -errno;
		goto err_close;
	}
	/* Bytes from before we opened are not ours to interpret. */
	tcflush(t->fd, TCIOFLUSH);
	/* One owner of the MCU at a time; best effort (not every tty supports it). */
	ioctl(t->fd, TIOCEXCL);
	*ret_ctx = t;
	return 0;

err_close:
	close(t->fd);
err_free:
	free(t);
	return r;
}

static void tty_close(void *ctx)
{
	struct tty *t = ctx;
	close(t->fd);
	free(t);
}

static ssize_t tty_read(void *ctx, uint8_t *buf, size_t cap, int timeout_ms)
{
	struct tty *t = ctx;
	struct pollfd p = {.fd = t->fd, .events = POLLIN};
	int n = poll(&p, 1, timeout_ms);
	if (n < 0)
		return errno == EINTR ? -EINTR : -errno;
	if (n == 0)
		return -ETIMEDOUT;
	if ((p.revents & (POLLHUP | POLLERR | POLLNVAL)) && !(p.revents & POLLIN))
		return -ENOTCONN;
	ssize_t got = read(t->fd, buf, cap);
	if (got > 0)
		return got;
	if (got == 0)
		return -ENOTCONN; /* hangup */
	if (errno == EAGAIN || errno == EINTR)
		return -ETIMEDOUT;
	return is_hangup(errno) ? -ENOTCONN : -errno;
}

static ssize_t tty_write(void *ctx, const uint8_t *buf, size_t len, int timeout_ms)
{
	struct tty *t = ctx;
	size_t done = 0;
	while (done < len) {
		struct pollfd p = {.fd = t->fd, .events = POLLOUT};
		int n = poll(&p, 1, timeout_ms);
		if (n < 0) {
			if (errno == EINTR)
				continue;
			return -errno;
		}
		if (n == 0)
			return -ETIMEDOUT;
		if (p.revents & (POLLHUP | POLLERR | POLLNVAL))
			return -ENOTCONN;
		ssize_t w = write(t->fd, buf + done, len - done);
		if (w < 0) {
			if (errno == EAGAIN || errno == EINTR)
				continue;
			return is_hangup(errno) ? -ENOTCONN : -errno;
		}
		done += (size_t)w;
	}
	return (ssize_t)len;
}

static int tty_fd(void *ctx)
{
	return ((struct tty *)ctx)->fd;
}

const struct fscan_serial_ops fscan_serial_termios_ops = {
	.name = "termios",
	.open = tty_open,
	.close = tty_close,
	.read = tty_read,
	.write = tty_write,
	.fd = tty_fd,
};
