/* Fake serial transport: an AF_UNIX stream socket pair per connection. The link reads and
 * writes one end; the other end (the peer) belongs to the fake device, which lives in a small
 * registry keyed by device name so that it outlives the link's close/reopen cycles, as a
 * /dev node outlives its users. A device with the MCU attached serves each connection with
 * the MCU model (serial_mcu_model.c) on the peer end. */
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
	bool mcu;              /* fscan_serial_fake_attach_mcu(): a model serves each connection */
	struct fscan_mcu_model *model; /* the current connection's, or NULL */
	int scans_before;      /* sequences completed by the models of earlier connections */
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

/* Forgets a device nobody uses any more (unless it is unplugged or has the MCU attached: that
 * state must survive). */
static void release_device(struct device *d)
{
	if (d->users || d->unplugged || d->mcu)
		return;
	if (d->peer >= 0)
		close(d->peer);
	memset(d, 0, sizeof(*d));
}

/* Stops the device's MCU model (its count kept for fscan_serial_fake_mcu_scans()), then closes
 * the peer end: in this order, so that the model never serves a descriptor closed under it.
 * Called with devices_lock held. */
static void stop_mcu(struct device *d)
{
	if (d->model) {
		int n = fscan_mcu_model_scans(d->model);
		d->scans_before += n > 0 ? n : 0;
		fscan_mcu_model_stop(d->model);
		d->model = NULL;
	}
	if (d->peer >= 0) {
		close(d->peer);
		d->peer = -1;
	}
}

/* Pulls the cable. Called with devices_lock held. */
static void unplug_device(struct device *d)
{
	d->unplugged = true;
	stop_mcu(d);
}

/* A model that hung up (fscan_mcu_model_hangup_on_sequence) pulled the cable: the device
 * becomes unplugged. Called with devices_lock held, before anything that looks at the device. */
static void note_hangup(struct device *d)
{
	if (d->model && fscan_mcu_model_hung_up(d->model) > 0)
		unplug_device(d);
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
	note_hangup(d);
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
	if (d->mcu) {
		/* The MCU is powered by its cable: each connection boots it (EVT_BOOT first). */
		r = fscan_mcu_model_start(sv[1], &d->model);
		if (r < 0) {
			d->model = NULL;
			free(c);
			c = NULL;
			close(sv[0]);
			close(sv[1]);
			goto out_release;
		}
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
	pthread_mutex_lock(&devices_lock);
	note_hangup(c->dev);
	if (c->dev->mcu)
		stop_mcu(c->dev); /* before our end closes: the model never writes into a closed pair */
	close(c->fd);
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

/* Plugs the cable back. Called with devices_lock held. */
static void plug_device(struct device *d)
{
	d->unplugged = false;
	release_device(d);
}

/* The attached device called `name` (hangups noted), or NULL. Called with devices_lock held. */
static struct device *mcu_device(const char *name)
{
	struct device *d = name ? find_device(name, false) : NULL;
	if (!d || !d->mcu)
		return NULL;
	note_hangup(d);
	return d;
}

/* Applies fn under devices_lock to the link's device, or without a link to the attached device
 * `name`. -EINVAL when there is none. */
static int on_device(struct fscan_serial *link, const char *name, void (*fn)(struct device *))
{
	pthread_mutex_lock(&devices_lock);
	struct device *d = link ? device_of(link) : mcu_device(name);
	if (d)
		fn(d);
	pthread_mutex_unlock(&devices_lock);
	return d ? 0 : -EINVAL;
}

int fscan_serial_fake_unplug(struct fscan_serial *link)
{
	return link ? on_device(link, NULL, unplug_device) : -EINVAL;
}

int fscan_serial_fake_plug(struct fscan_serial *link)
{
	return link ? on_device(link, NULL, plug_device) : -EINVAL;
}

int fscan_serial_fake_open_count(struct fscan_serial *link)
{
	pthread_mutex_lock(&devices_lock);
	struct device *d = device_of(link);
	int r = d ? d->open_count : -EINVAL;
	pthread_mutex_unlock(&devices_lock);
	return r;
}

/* ---- the fake device with the MCU on it ---- */

int fscan_serial_fake_attach_mcu(const char *device)
{
	if (!device || !strcmp(device, FSCAN_SERIAL_FAKE_MISSING_DEVICE))
		return -EINVAL;
	pthread_mutex_lock(&devices_lock);
	struct device *d = find_device(device, true);
	int r = !d ? -ENOMEM : d->users ? -EBUSY : 0;
	if (!r) {
		d->mcu = true;
		d->unplugged = false;
		d->scans_before = 0;
	}
	pthread_mutex_unlock(&devices_lock);
	return r;
}

int fscan_serial_fake_device_unplug(const char *device)
{
	return device ? on_device(NULL, device, unplug_device) : -EINVAL;
}

int fscan_serial_fake_device_plug(const char *device)
{
	return device ? on_device(NULL, device, plug_device) : -EINVAL;
}

/* Applies fn to the model serving the attached device `name` under devices_lock: its return,
 * -EINVAL when there is no such device, -ENOTCONN when no link is connected. */
static int on_model(const char *name, int (*fn)(struct fscan_mcu_model *))
{
	pthread_mutex_lock(&devices_lock);
	struct device *d = mcu_device(name);
	int r = !d ? -EINVAL : !d->model ? -ENOTCONN : fn(d->model);
	pthread_mutex_unlock(&devices_lock);
	return r;
}

int fscan_serial_fake_mcu_press(const char *device)
{
	return on_model(device, fscan_mcu_model_press);
}

int fscan_serial_fake_mcu_unplug_on_fire(const char *device)
{
	return on_model(device, fscan_mcu_model_hangup_on_sequence);
}

int fscan_serial_fake_mcu_scans(const char *device)
{
	pthread_mutex_lock(&devices_lock);
	struct device *d = mcu_device(device);
	int r = -EINVAL;
	if (d) {
		int n = d->model ? fscan_mcu_model_scans(d->model) : 0;
		r = d->scans_before + (n > 0 ? n : 0);
	}
	pthread_mutex_unlock(&devices_lock);
	return r;
}
