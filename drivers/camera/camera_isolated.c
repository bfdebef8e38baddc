/* Camera backend that runs another backend in a child process (fscan_camera_isolated_ops).
 *
 * Why: libcamera 0.0.3 aborts the whole process when a camera vanishes while requests are
 * queued (PipelineHandler::stop() asserts queuedRequests_.empty(); tests/vm/README.md), and a
 * camera stack can hang in a driver ioctl. In the booth that process is facescand. Here the
 * inner backend lives in a child forked at open(); every op is a request over a socketpair with
 * a deadline. When the child dies or misses a deadline it is killed and reaped, the op fails
 * (-ENODEV: the camera is gone; -ETIMEDOUT: it stopped answering) and every later op fails with
 * -ENODEV at once, so the caller reports the camera as failed and lives on.
 *
 * The child is forked, not exec'ed: it runs the inner backend's code from this very binary and
 * reads the open parameters from its copy of the parent's memory. It keeps only the socket and
 * stdio (a lock the daemon holds must not outlive the daemon in it) and dies with its parent. */
#define _GNU_SOURCE
#include "camera_internal.h"

#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* How long the child may take beyond an op's own timeout: opening cameras enumerates devices
 * (seconds under emulation), the others should be quick. */
#define OPEN_DEADLINE_MS 30000
#define OP_DEADLINE_MS 10000
#define FRAME_GRACE_MS 5000
/* The largest frame the child may send: 16384^2 RGB is the configure() limit. */
#define MAX_FRAME_BYTES ((uint64_t)16384u * 16384u * 3u)

enum op { OP_COUNT = 1, OP_INFO, OP_CONFIGURE, OP_ARM, OP_NEXT_FRAME, OP_DISARM, OP_CLOSE };

struct request {
	int32_t op;
	uint32_t a, b; /* info: camera; arm: first_seq, n_triggers */
	int32_t timeout_ms;
	struct fscan_camera_config cfg;
};

struct reply {
	int32_t rc;
	struct fscan_camera_info info;
	struct fscan_camera_raw_frame raw; /* raw.frame.data is not sent; data_bytes follow */
	uint64_t data_bytes;
};

struct ctx {
	pid_t pid; /* 0 once reaped */
	int fd;	   /* -1 once closed */
	int count;
};

static int64_t mono_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

/* Reads or writes exactly n bytes before deadline_ms (CLOCK_MONOTONIC; < 0: no deadline).
 * 0, -ENODEV (peer gone), -ETIMEDOUT, or another -errno. */
static int io_all(int fd, void *buf, size_t n, bool writing, int64_t deadline_ms)
{
	char *p = buf;
	while (n > 0) {
		int wait = -1;
		if (deadline_ms >= 0) {
			int64_t left = deadline_ms - mono_ms();
			if (left <= 0)
				return -ETIMEDOUT;
			wait = left > 60000 ? 60000 : (int)left;
		}
		struct pollfd pfd = {fd, (short)(writing ? POLLOUT : POLLIN), 0};
		int r = poll(&pfd, 1, wait);
		if (r < 0 && errno == EINTR)
			continue;
		if (r < 0)
			return -errno;
		if (r == 0)
			continue;
		ssize_t k = writing ? send(fd, p, n, MSG_NOSIGNAL) : recv(fd, p, n, 0);
		if (k < 0 && (errno == EINTR || errno == EAGAIN))
			continue;
		if (k < 0)
			return errno == EPIPE || errno == ECONNRESET ? -ENODEV : -errno;
		if (k == 0)
			return -ENODEV;
		p += k;
		n -= (size_t)k;
	}
	return 0;
}

/* ---- the child --------------------------------------------------------------------------- */

static void serve_reply(int fd, struct reply *rep, const void *data)
{
	if (io_all(fd, rep, sizeof(*rep), true, -1) < 0)
		_exit(0);
	if (rep->data_bytes && io_all(fd, (void *)data, (size_t)rep->data_bytes, true, -1) < 0)
		_exit(0);
}

static void serve(int fd, const struct fscan_camera_ops *inner, const struct fscan_camera_params *params)
{
	void *ictx = NULL;
	struct reply rep;
	memset(&rep, 0, sizeof(rep));
	rep.rc = inner->open(params, &ictx);
	if (rep.rc == 0)
		rep.rc = inner->count(ictx);
	serve_reply(fd, &rep, NULL);
	if (rep.rc <= 0)
		_exit(0);
	for (;;) {
		struct request req;
		/* The parent gone (EOF) is a close. */
		if (io_all(fd, &req, sizeof(req), false, -1) < 0)
			req.op = OP_CLOSE;
		memset(&rep, 0, sizeof(rep));
		switch (req.op) {
		case OP_COUNT:
			rep.rc = inner->count(ictx);
			break;
		case OP_INFO:
			rep.rc = inner->info(ictx, req.a, &rep.info);
			break;
		case OP_CONFIGURE:
			rep.rc = inner->configure(ictx, &req.cfg);
			break;
		case OP_ARM:
			rep.rc = inner->arm(ictx, req.a, req.b);
			break;
		case OP_NEXT_FRAME:
			rep.rc = inner->next_frame(ictx, req.timeout_ms, &rep.raw);
			if (rep.rc == 0 && rep.raw.frame.data)
				rep.data_bytes = (uint64_t)rep.raw.frame.stride * rep.raw.frame.height;
			break;
		case OP_DISARM:
			rep.rc = inner->disarm(ictx);
			break;
		case OP_CLOSE:
		default:
			inner->close(ictx);
			rep.rc = 0;
			serve_reply(fd, &rep, NULL);
			_exit(0);
		}
		serve_reply(fd, &rep, rep.raw.frame.data);
		free(rep.raw.frame.data);
	}
}

/* In the child, right after fork(): only the socket (as fd 3) and stdio stay open, and the
 * child dies with its parent. Never returns. */
static void child_main(int fd, pid_t parent, const struct fscan_camera_params *params)
{
	prctl(PR_SET_PDEATHSIG, SIGKILL);
	if (getppid() != parent)
		_exit(0);
	if (fd != 3) {
		if (dup2(fd, 3) < 0)
			_exit(0);
		fd = 3;
	}
	close_range(4, ~0u, 0);
	const struct fscan_camera_ops *inner = params->isolated_inner ? params->isolated_inner
								      : &fscan_camera_libcamera_ops;
	serve(fd, inner, params);
	_exit(0);
}

/* ---- the parent -------------------------------------------------------------------------- */

/* Kills and reaps the child (if still there) and closes the socket. */
static void bury(struct ctx *c)
{
	if (c->fd >= 0)
		close(c->fd);
	c->fd = -1;
	if (c->pid > 0) {
		kill(c->pid, SIGKILL);
		while (waitpid(c->pid, NULL, 0) < 0 && errno == EINTR)
			;
	}
	c->pid = 0;
}

/* One request, one reply (and a frame's bytes into *ret_data when it has some). A child that
 * dies or misses the deadline is buried: -ENODEV or -ETIMEDOUT, then -ENODEV for good. */
static int call(struct ctx *c, const struct request *req, int deadline_ms, struct reply *ret_rep,
		uint8_t **ret_data)
{
	if (c->fd < 0)
		return -ENODEV;
	int64_t deadline = mono_ms() + deadline_ms;
	int r = io_all(c->fd, (void *)req, sizeof(*req), true, deadline);
	if (r == 0)
		r = io_all(c->fd, ret_rep, sizeof(*ret_rep), false, deadline);
	if (r == 0 && ret_rep->data_bytes) {
		if (!ret_data || ret_rep->data_bytes > MAX_FRAME_BYTES) {
			r = -EPROTO;
		} else {
			uint8_t *data = malloc((size_t)ret_rep->data_bytes);
			r = data ? io_all(c->fd, data, (size_t)ret_rep->data_bytes, false, deadline) : -ENOMEM;
			if (r == 0)
				*ret_data = data;
			else
				free(data);
		}
	}
	if (r < 0 && r != -ENOMEM) {
		bury(c);
		return r == -ETIMEDOUT ? -ETIMEDOUT : -ENODEV;
	}
	return r < 0 ? r : ret_rep->rc;
}

static int iso_open(const struct fscan_camera_params *params, void **ret_ctx)
{
	int sv[2];
	if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) < 0)
		return -errno;
	pid_t parent = getpid();
	pid_t pid = fork();
	if (pid < 0) {
		int e = -errno;
		close(sv[0]);
		close(sv[1]);
		return e;
	}
	if (pid == 0) {
		close(sv[0]);
		child_main(sv[1], parent, params);
	}
	close(sv[1]);
	struct ctx *c = calloc(1, sizeof(*c));
	if (!c) {
		struct ctx tmp = {pid, sv[0], 0};
		bury(&tmp);
		return -ENOMEM;
	}
	c->pid = pid;
	c->fd = sv[0];
	struct reply rep;
	int r = io_all(c->fd, &rep, sizeof(rep), false, mono_ms() + OPEN_DEADLINE_MS);
	if (r == 0)
		r = rep.rc;
	if (r <= 0) {
		if (r == 0)
			r = -ENODEV;
		bury(c);
		free(c);
		return r;
	}
	c->count = r;
	*ret_ctx = c;
	return 0;
}

static void iso_close(void *vctx)
{
	struct ctx *c = vctx;
	if (c->fd >= 0) {
		struct request req = {.op = OP_CLOSE};
		struct reply rep;
		call(c, &req, OP_DEADLINE_MS, &rep, NULL);
	}
	bury(c);
	free(c);
}

static int iso_count(void *vctx)
{
	return ((struct ctx *)vctx)->count;
}

static int iso_info(void *vctx, uint32_t camera, struct fscan_camera_info *ret_info)
{
	struct request req = {.op = OP_INFO, .a = camera};
	struct reply rep;
	int r = call(vctx, &req, OP_DEADLINE_MS, &rep, NULL);
	if (r == 0)
		*ret_info = rep.info;
	return r;
}

static int iso_configure(void *vctx, const struct fscan_camera_config *cfg)
{
	struct request req = {.op = OP_CONFIGURE, .cfg = *cfg};
	struct reply rep;
	return call(vctx, &req, OP_DEADLINE_MS, &rep, NULL);
}

static int iso_arm(void *vctx, uint32_t first_seq, uint32_t n_triggers)
{
	struct request req = {.op = OP_ARM, .a = first_seq, .b = n_triggers};
	struct reply rep;
	return call(vctx, &req, OP_DEADLINE_MS, &rep, NULL);
}

static int iso_next_frame(void *vctx, int timeout_ms, struct fscan_camera_raw_frame *ret_frame)
{
	/* A wait for ever is asked in bounded slices, so that a child that stopped answering is
	 * still found out. */
	struct request req = {.op = OP_NEXT_FRAME, .timeout_ms = timeout_ms < 0 ? 60000 : timeout_ms};
	struct reply rep;
	uint8_t *data = NULL;
	int r;
	do
		r = call(vctx, &req, req.timeout_ms + FRAME_GRACE_MS, &rep, &data);
	while (r == -ETIMEDOUT && timeout_ms < 0 && ((struct ctx *)vctx)->fd >= 0);
	if (r < 0)
		return r;
	*ret_frame = rep.raw;
	ret_frame->frame.data = data;
	return 0;
}

static int iso_disarm(void *vctx)
{
	struct ctx *c = vctx;
	/* Nothing is queued in a child that is gone. */
	if (c->fd < 0)
		return 0;
	struct request req = {.op = OP_DISARM};
	struct reply rep;
	return call(c, &req, OP_DEADLINE_MS, &rep, NULL);
}

const struct fscan_camera_ops fscan_camera_isolated_ops = {
	"isolated", iso_open, iso_close, iso_count, iso_info, iso_configure, iso_arm, iso_next_frame, iso_disarm,
};
