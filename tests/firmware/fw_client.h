/* A minimal host side of the protocol over a file descriptor, for the firmware tests that
 * talk to a real firmware process (QEMU, facescan-fw-native). Uses the shared codec only. */
#ifndef FACESCAN_TESTS_FW_CLIENT_H
#define FACESCAN_TESTS_FW_CLIENT_H

#include <errno.h>
#include <poll.h>
#include <stdint.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "protocol/protocol.h"

#define FWC_MAX_EVENTS 32

struct fwc {
	int fd;
	uint8_t seq;
	struct fs_decoder dec;
	int bad_frames;
	/* Events received while waiting for responses, oldest first. */
	struct fs_frame events[FWC_MAX_EVENTS];
	int n_events;
};

static inline void fwc_init(struct fwc *c, int fd)
{
	memset(c, 0, sizeof(*c));
	c->fd = fd;
	fs_decoder_init(&c->dec);
}

static inline int64_t fwc_now_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static inline int fwc_send(struct fwc *c, const struct fs_frame *f)
{
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t n = 0;
	int r = fs_frame_encode(f, buf, sizeof(buf), &n);
	if (r < 0)
		return r;
	for (size_t off = 0; off < n;) {
		ssize_t w = write(c->fd, buf + off, n - off);
		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0)
			return -EIO;
		off += (size_t)w;
	}
	return 0;
}

/* Next frame of any kind within timeout_ms: 1, 0 on timeout, -errno on I/O error/EOF. */
static inline int fwc_recv(struct fwc *c, struct fs_frame *ret, int timeout_ms)
{
	int64_t deadline = fwc_now_ms() + timeout_ms;
	for (;;) {
		uint8_t b;
		int left = (int)(deadline - fwc_now_ms());
		if (left < 0)
			return 0;
		struct pollfd p = { .fd = c->fd, .events = POLLIN };
		int pr = poll(&p, 1, left);
		if (pr < 0 && errno == EINTR)
			continue;
		if (pr < 0)
			return -errno;
		if (pr == 0)
			return 0;
		ssize_t n = read(c->fd, &b, 1);
		if (n < 0 && (errno == EINTR || errno == EAGAIN))
			continue;
		if (n <= 0)
			return -EIO;
		int r = fs_decoder_feed(&c->dec, b, ret);
		if (r < 0)
			c->bad_frames++;
		if (r == 1)
			return 1;
	}
}

/* Send a command (seq assigned here) and wait for its response; events that arrive first
 * are kept in c->events. Returns 1 with *ret filled, 0 on timeout, -errno. */
static inline int fwc_transact(struct fwc *c, struct fs_frame *cmd, struct fs_frame *ret,
			       int timeout_ms)
{
	cmd->seq = ++c->seq;
	int r = fwc_send(c, cmd);
	if (r < 0)
		return r;
	int64_t deadline = fwc_now_ms() + timeout_ms;
	for (;;) {
		struct fs_frame f;
		r = fwc_recv(c, &f, (int)(deadline - fwc_now_ms()));
		if (r <= 0)
			return r;
		if (fs_type_is_event(f.type)) {
			if (c->n_events < FWC_MAX_EVENTS)
				c->events[c->n_events++] = f;
			continue;
		}
		if (f.seq == cmd->seq) {
			*ret = f;
			return 1;
		}
	}
}

static inline int fwc_cmd(struct fwc *c, uint8_t type, struct fs_frame *ret, int timeout_ms)
{
	struct fs_frame f;
	fs_frame_init(&f, type, 0);
	return fwc_transact(c, &f, ret, timeout_ms);
}

/* Wait for an event of `type` (from the kept ones first). 1, 0 on timeout, -errno. */
static inline int fwc_wait_event(struct fwc *c, uint8_t type, struct fs_frame *ret,
				 int timeout_ms)
{
	for (int i = 0; i < c->n_events; i++) {
		if (c->events[i].type == type) {
			*ret = c->events[i];
			memmove(&c->events[i], &c->events[i + 1],
				(size_t)(c->n_events - i - 1) * sizeof(c->events[0]));
			c->n_events--;
			return 1;
		}
	}
	int64_t deadline = fwc_now_ms() + timeout_ms;
	for (;;) {
		struct fs_frame f;
		int r = fwc_recv(c, &f, (int)(deadline - fwc_now_ms()));
		if (r <= 0)
			return r;
		if (f.type == type) {
			*ret = f;
			return 1;
		}
		if (fs_type_is_event(f.type) && c->n_events < FWC_MAX_EVENTS)
			c->events[c->n_events++] = f;
	}
}

#endif
