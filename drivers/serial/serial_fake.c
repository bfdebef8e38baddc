/* Fake serial transport: an AF_UNIX stream socket pair per connection. The link reads and
 * writes one end; the other end (the peer) belongs to the fake device, which lives in a small
 * registry keyed by device name so that it outlives the link's close/reopen cycles, as a
 * /dev node outlives its users. */
#define _GNU_SOURCE
#include "facescan/serial_fake.h"
#include "serial_internal.h"

#include <errno.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define MAX_DEVICES 16

struct device {
	bool used;
	char name[64];
	bool unplugged;
	int peer;            /* peer end of the current connection, -1 if none */
	int users;           /* open connections (0 or 1) */
	int open_count;
	struct fs_decoder dec; /* for fscan_serial_fake_peer_recv */
};

static struct device devices[MAX_DEVICES];
static pthread_mutex_t devices_lock = PTHREAD_MUTEX_INITIALIZER;

struct conn {
	struct device *dev;
	int fd;
};

/* Finds (or with create, adds) the device entry. Called with devices_lock held. */
static struct device *find_device(const char *name, bool create)
{
	struct device *free_slot = NULL;
	for (int i = 0; i < MAX_DEVICES; i++) {
		if (devices[i].used && !strcmp(devices[i].name, name))
			return &devices[i];
		if (!devices[i].used && !free_slot)
			free_slot = &devices[i];
	}
	if (!create || !free_slot || strlen(name) >= sizeof(free_slot->name))
		return NULL;
	memset(free_slot, 0, sizeof(*free_slot));
	free_slot->used = true;
	free_slot->peer = -1;
	snprintf(free_slot->name, sizeof(free_slot->name), "%s", name);
	return free_slot;
}

/* Forgets a device nobody uses any more (unless it is unplugged: that state must survive). */
static void release_device(struct device *d)
{
	if (d->users || d->unplugged)
		return;
	if (d->peer >= 0)
		close(d->peer);
	memset(d, 0, sizeof(*d));
}

static int fake_open(const struct fscan_serial_config *cfg, void **ret_ctx)
{
	if (!strcmp(cfg->device, FSCAN_SERIAL_FAKE_MISSING_DEVICE))
		return -ENOENT;
	pthread_mutex_lock(&devices_lock);
	int r = 0;
	struct conn *c = NULL;
	struct device *d = find_device(cfg->device, true);
	if (!d) {
		r = -ENOMEM;
		goto out;
	}
	if (d->unplugged) {
		r = -ENODEV;
		goto out;
	}
	if (d->users) {
		r = -EBUSY;
		goto out;
	}
	int sv[2];
	if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) < 0) {
		r = -errno;
		goto out_release;
	}
	c = calloc(1, sizeof(*c));
	if (!c) {
		close(sv[0]);
		close(sv[1]);
		r = -ENOMEM;
		goto out_release;
	}
	if (d->peer >= 0)
		close(d->peer);
	d->peer = sv[1];
	d->users = 1;
	d->open_count++;
	fs_decoder_init(&d->dec);
	c->dev = d;
	c->fd = sv[0];
	*ret_ctx = c;
	goto out;
out_release:
	release_device(d);
out:
	pthread_mutex_unlock(&devices_lock);
	return r;
}

static void fake_close(void *ctx)
{
	struct conn *c = ctx;
	close(c->fd);
	pthread_mutex_lock(&devices_lock);
	c->dev->users = 0;
	release_device(c->dev);
	pthread_mutex_unlock(&devices_lock);
	free(c);
}

static ssize_t fake_read(void *ctx, uint8_t *buf, size_t cap, int timeout_ms)
{
	struct conn *c = ctx;
	struct pollfd p = {.fd = c->fd, .events = POLLIN};
	int n = poll(&p, 1, timeout_ms);
	if (n < 0)
		return -errno;
	if (n == 0)
		return -ETIMEDOUT;
	ssize_t got = recv(c->fd, buf, cap, MSG_DONTWAIT);
	if (got == 0)
		return -ENOTCONN; /* peer closed: unplugged */
	if (got < 0) {
		if (errno == EAGAIN)
			return -ETIMEDOUT;
		return errno == ECONNRESET ? -ENOTCONN : -errno;
	}
	return got;
}

static ssize_t fake_write(void *ctx, const uint8_t *buf, size_t len, int timeout_ms)
{
	struct conn *c = ctx;
	size_t done = 0;
	while (done < len) {
		struct pollfd p = {.fd = c->fd, .events = POLLOUT};
		int n = poll(&p, 1, timeout_ms);
		if (n < 0)
			return -errno;
		if (n == 0)
			return -ETIMEDOUT;
		if (p.revents & (POLLHUP | POLLERR))
			return -ENOTCONN;
		ssize_t w = send(c->fd, buf + done, len - done, MSG_NOSIGNAL | MSG_DONTWAIT);
		if (w < 0) {
			if (errno == EAGAIN)
				continue;
			return errno == EPIPE || errno == ECONNRESET ? -ENOTCONN : -errno;
		}
		done += (size_t)w;
	}
	return (ssize_t)len;
}

static int fake_fd(void *ctx)
{
	return ((struct conn *)ctx)->fd;
}

const struct fscan_serial_ops fscan_serial_fake_ops = {
	.name = "fake",
	.open = fake_open,
	.close = fake_close,
	.read = fake_read,
	.write = fake_write,
	.fd = fake_fd,
};

/* ---- back doors ---- */

static struct device *device_of(struct fscan_serial *link)
{
	if (!link || link->ops != &fscan_serial_fake_ops)
		return NULL;
	return find_device(link->device, false);
}

int fscan_serial_fake_peer_fd(struct fscan_serial *link)
{
	pthread_mutex_lock(&devices_lock);
	struct device *d = device_of(link);
	int r = !d ? -EINVAL : d->peer >= 0 ? d->peer : -ENOTCONN;
	pthread_mutex_unlock(&devices_lock);
	return r;
}

ssize_t fscan_serial_fake_peer_write(struct fscan_serial *link, const uint8_t *buf, size_t len)
{
	int fd = fscan_serial_fake_peer_fd(link);
	if (fd < 0)
		return fd;
	size_t done = 0;
	while (done < len) {
		ssize_t w = send(fd, buf + done, len - done, MSG_NOSIGNAL);
		if (w < 0)
			return errno == EPIPE ? -ENOTCONN : -errno;
		done += (size_t)w;
	}
	return (ssize_t)len;
}

ssize_t fscan_serial_fake_peer_read(struct fscan_serial *link, uint8_t *buf, size_t cap, int timeout_ms)
{
	int fd = fscan_serial_fake_peer_fd(link);
	if (fd < 0)
		return fd;
	struct pollfd p = {.fd = fd, .events = POLLIN};
	int n = poll(&p, 1, timeout_ms);
	if (n < 0)
		return -errno;
	if (n == 0)
		return -ETIMEDOUT;
	ssize_t got = recv(fd, buf, cap, MSG_DONTWAIT);
	if (got == 0)
		return -ENOTCONN;
	return got < 0 ? -errno : got;
}

int fscan_serial_fake_peer_send(struct fscan_serial *link, const struct fs_frame *frame)
{
	if (!frame)
		return -EINVAL;
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t len;
	int r = fs_frame_encode(frame, buf, sizeof(buf), &len);
	if (r < 0)
		return r;
	ssize_t w = fscan_serial_fake_peer_write(link, buf, len);
	return w < 0 ? (int)w : 0;
}

int fscan_serial_fake_peer_recv(struct fscan_serial *link, struct fs_frame *ret_frame, int timeout_ms)
{
	if (!ret_frame)
		return -EINVAL;
	pthread_mutex_lock(&devices_lock);
	struct device *d = device_of(link);
	pthread_mutex_unlock(&devices_lock);
	if (!d)
		return -EINVAL;
	for (;;) {
		uint8_t byte;
		ssize_t n = fscan_serial_fake_peer_read(link, &byte, 1, timeout_ms);
		if (n < 0)
			return (int)n;
		if (fs_decoder_feed(&d->dec, byte, ret_frame) == 1)
			return 0;
	}
}

int fscan_serial_fake_unplug(struct fscan_serial *link)
{
	pthread_mutex_lock(&devices_lock);
	struct device *d = device_of(link);
	int r = -EINVAL;
	if (d) {
		d->unplugged = true;
		if (d->peer >= 0) {
			close(d->peer);
			d->peer = -1;
		}
		r = 0;
	}
	pthread_mutex_unlock(&devices_lock);
	return r;
}

int fscan_serial_fake_plug(struct fscan_serial *link)
{
	pthread_mutex_lock(&devices_lock);
	struct device *d = device_of(link);
	int r = -EINVAL;
	if (d) {
		d->unplugged = false;
		release_device(d);
		r = 0;
	}
	pthread_mutex_unlock(&devices_lock);
	return r;
}

int fscan_serial_fake_open_count(struct fscan_serial *link)
{
	pthread_mutex_lock(&devices_lock);
	struct device *d = device_of(link);
	int r = d ? d->open_count : -EINVAL;
	pthread_mutex_unlock(&devices_lock);
	return r;
}
