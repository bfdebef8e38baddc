/* Common part of the serial driver: the firmware protocol over a byte transport. Framing is the
 * protocol's own codec (firmware/protocol); this file adds timeouts, the request/response rule,
 * an event queue and reconnection after a hangup. */
#include "serial_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static uint64_t mono_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (uint64_t)ts.tv_sec * 1000u + (uint64_t)ts.tv_nsec / 1000000u;
}

/* Milliseconds left of timeout_ms since start (<0 = forever stays <0). */
static int remaining(int timeout_ms, uint64_t start)
{
	if (timeout_ms < 0)
		return -1;
	uint64_t spent = mono_ms() - start;
	return spent >= (uint64_t)timeout_ms ? 0 : (int)(timeout_ms - spent);
}

static void reset_rx(struct fscan_serial *link)
{
	fs_decoder_init(&link->dec);
	link->rx_pos = link->rx_len = 0;
}

static void go_down(struct fscan_serial *link)
{
	if (!link->ctx)
		return;
	link->ops->close(link->ctx);
	link->ctx = NULL;
	link->stats.hangups++;
	reset_rx(link);
}

/* Reopens a link that went down. 0 or -ENOTCONN. */
static int ensure_up(struct fscan_serial *link)
{
	if (link->ctx)
		return 0;
	void *ctx;
	if (link->ops->open(&link->cfg, &ctx) < 0)
		return -ENOTCONN;
	link->ctx = ctx;
	link->stats.reconnects++;
	reset_rx(link);
	return 0;
}

int fscan_serial_create(const struct fscan_serial_ops *ops, const struct fscan_serial_config *cfg,
			struct fscan_serial **ret_link)
{
	if (!ops || !cfg || !ret_link || !cfg->device || !*cfg->device)
		return -EINVAL;
	struct fscan_serial *link = calloc(1, sizeof(*link));
	if (!link)
		return -ENOMEM;
	int r = -ENOMEM;
	link->device = strdup(cfg->device);
	if (!link->device)
		goto err_free;
	link->ops = ops;
	link->cfg = *cfg;
	link->cfg.device = link->device;
	if (!link->cfg.baud)
		link->cfg.baud = 115200;
	reset_rx(link);
	r = ops->open(&link->cfg, &link->ctx);
	if (r < 0)
		goto err_free;
	*ret_link = link;
	return 0;

err_free:
	free(link->device);
	free(link);
	return r;
}

void fscan_serial_destroy(struct fscan_serial *link)
{
	if (!link)
		return;
	if (link->ctx)
		link->ops->close(link->ctx);
	free(link->device);
	free(link);
}

int fscan_serial_send(struct fscan_serial *link, const struct fs_frame *frame, int timeout_ms)
{
	if (!link || !frame)
		return -EINVAL;
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t len;
	int r = fs_frame_encode(frame, buf, sizeof(buf), &len);
	if (r < 0)
		return r;
	r = ensure_up(link);
	if (r < 0)
		return r;
	ssize_t n = link->ops->write(link->ctx, buf, len, timeout_ms);
	if (n == -ENOTCONN) {
		go_down(link);
		return -ENOTCONN;
	}
	if (n < 0)
		return (int)n;
	link->stats.frames_tx++;
	return 0;
}

/* Next good frame from the wire (not from the event queue). */
static int recv_wire(struct fscan_serial *link, struct fs_frame *ret, int timeout_ms)
{
	int r = ensure_up(link);
	if (r < 0)
		return r;
	uint64_t start = mono_ms();
	for (;;) {
		while (link->rx_pos < link->rx_len) {
			int d = fs_decoder_feed(&link->dec, link->rx[link->rx_pos++], ret);
			if (d == 1) {
				link->stats.frames_rx++;
				return 0;
			}
			if (d < 0)
				link->stats.bad_frames++;
		}
		ssize_t n = link->ops->read(link->ctx, link->rx, sizeof(link->rx), remaining(timeout_ms, start));
		if (n == -ENOTCONN) {
			go_down(link);
			return -ENOTCONN;
		}
		if (n < 0)
			return (int)n;
		link->rx_pos = 0;
		link->rx_len = (size_t)n;
	}
}

static void queue_event(struct fscan_serial *link, const struct fs_frame *f)
{
	if (link->ev_len == FSCAN_SERIAL_EVENT_QUEUE) { /* drop the oldest */
		link->ev_head = (link->ev_head + 1) % FSCAN_SERIAL_EVENT_QUEUE;
		link->ev_len--;
		link->stats.events_dropped++;
	}
	link->events[(link->ev_head + link->ev_len) % FSCAN_SERIAL_EVENT_QUEUE] = *f;
	link->ev_len++;
}

static bool pop_event(struct fscan_serial *link, struct fs_frame *ret)
{
	if (!link->ev_len)
		return false;
	*ret = link->events[link->ev_head];
	link->ev_head = (link->ev_head + 1) % FSCAN_SERIAL_EVENT_QUEUE;
	link->ev_len--;
	return true;
}

int fscan_serial_recv(struct fscan_serial *link, struct fs_frame *ret_frame, int timeout_ms)
{
	if (!link || !ret_frame)
		return -EINVAL;
	if (pop_event(link, ret_frame))
		return 0;
	return recv_wire(link, ret_frame, timeout_ms);
}

int fscan_serial_request(struct fscan_serial *link, struct fs_frame *cmd, struct fs_frame *ret_resp,
			 int timeout_ms)
{
	if (!link || !cmd || !fs_type_is_command(cmd->type))
		return -EINVAL;
	link->last_nack = FS_ERR_NONE;
	if (++link->seq == 0) /* seq 0 is what undecodable-frame NACKs carry */
		link->seq = 1;
	cmd->seq = link->seq;
	uint64_t start = mono_ms();
	int r = fscan_serial_send(link, cmd, timeout_ms);
	if (r < 0)
		return r;
	for (;;) {
		struct fs_frame f;
		r = recv_wire(link, &f, remaining(timeout_ms, start));
		if (r < 0)
			return r;
		if (fs_type_is_event(f.type)) {
			queue_event(link, &f);
			continue;
		}
		if (!fs_type_is_response(f.type) || f.seq != cmd->seq)
			continue; /* stale: an answer to an earlier request that timed out */
		if (ret_resp)
			*ret_resp = f;
		if (f.type == FS_RSP_NACK) {
			struct fs_nack nack;
			link->last_nack = fs_nack_get(&f, &nack) == 0 ? nack.err : FS_ERR_FRAMING;
			return -EREMOTEIO;
		}
		return 0;
	}
}

int fscan_serial_next_event(struct fscan_serial *link, struct fs_frame *ret_event, int timeout_ms)
{
	if (!link || !ret_event)
		return -EINVAL;
	if (pop_event(link, ret_event))
		return 0;
	uint64_t start = mono_ms();
	for (;;) {
		struct fs_frame f;
		int r = recv_wire(link, &f, remaining(timeout_ms, start));
		if (r < 0)
			return r;
		if (fs_type_is_event(f.type)) {
			*ret_event = f;
			return 0;
		}
	}
}

/* A request whose reply must be of type `want`. */
static int request_reply(struct fscan_serial *link, uint8_t type, uint8_t want, struct fs_frame *ret,
			 int timeout_ms)
{
	struct fs_frame cmd;
	fs_frame_init(&cmd, type, 0);
	int r = fscan_serial_request(link, &cmd, ret, timeout_ms);
	if (r < 0)
		return r;
	return ret->type == want ? 0 : -EBADMSG;
}

int fscan_serial_hello(struct fscan_serial *link, struct fs_hello *ret_hello, int timeout_ms)
{
	if (!ret_hello)
		return -EINVAL;
	struct fs_frame f;
	int r = request_reply(link, FS_CMD_HELLO, FS_RSP_HELLO, &f, timeout_ms);
	return r < 0 ? r : fs_hello_get(&f, ret_hello);
}

int fscan_serial_get_timing(struct fscan_serial *link, struct fs_timing *ret_timing, int timeout_ms)
{
	if (!ret_timing)
		return -EINVAL;
	struct fs_frame f;
	int r = request_reply(link, FS_CMD_GET_TIMING, FS_RSP_TIMING, &f, timeout_ms);
	return r < 0 ? r : fs_timing_get(&f, ret_timing);
}

int fscan_serial_set_timing(struct fscan_serial *link, const struct fs_timing *timing, int timeout_ms)
{
	if (!timing)
		return -EINVAL;
	struct fs_frame cmd, resp;
	fs_frame_init(&cmd, FS_CMD_SET_TIMING, 0);
	fs_timing_put(&cmd, timing);
	int r = fscan_serial_request(link, &cmd, &resp, timeout_ms);
	if (r < 0)
		return r;
	return resp.type == FS_RSP_ACK ? 0 : -EBADMSG;
}

int fscan_serial_status(struct fscan_serial *link, struct fs_status *ret_status, int timeout_ms)
{
	if (!ret_status)
		return -EINVAL;
	struct fs_frame f;
	int r = request_reply(link, FS_CMD_STATUS, FS_RSP_STATUS, &f, timeout_ms);
	return r < 0 ? r : fs_status_get(&f, ret_status);
}

int fscan_serial_command(struct fscan_serial *link, uint8_t type, int timeout_ms)
{
	if (type != FS_CMD_ARM && type != FS_CMD_DISARM && type != FS_CMD_FIRE && type != FS_CMD_ABORT &&
	    type != FS_CMD_CLEAR_FAULT)
		return -EINVAL;
	struct fs_frame f;
	int r = request_reply(link, type, FS_RSP_ACK, &f, timeout_ms);
	if (r < 0)
		return r;
	uint8_t acked;
	if (fs_ack_get(&f, &acked) < 0 || acked != type)
		return -EBADMSG;
	return 0;
}

uint8_t fscan_serial_last_nack(const struct fscan_serial *link)
{
	return link ? link->last_nack : FS_ERR_NONE;
}

void fscan_serial_flush_input(struct fscan_serial *link)
{
	if (!link)
		return;
	link->ev_head = link->ev_len = 0;
	reset_rx(link);
	if (!link->ctx)
		return;
	uint8_t junk[256];
	while (link->ops->read(link->ctx, junk, sizeof(junk), 0) > 0)
		;
}

int fscan_serial_reconnect(struct fscan_serial *link)
{
	if (!link)
		return -EINVAL;
	if (link->ctx) {
		link->ops->close(link->ctx);
		link->ctx = NULL;
	}
	reset_rx(link);
	void *ctx;
	int r = link->ops->open(&link->cfg, &ctx);
	if (r < 0)
		return r;
	link->ctx = ctx;
	link->stats.reconnects++;
	return 0;
}

bool fscan_serial_connected(const struct fscan_serial *link)
{
	return link && link->ctx;
}

int fscan_serial_fd(const struct fscan_serial *link)
{
	if (!link)
		return -EINVAL;
	return link->ctx ? link->ops->fd(link->ctx) : -ENOTCONN;
}

bool fscan_serial_pending(const struct fscan_serial *link)
{
	return link && (link->ev_len || link->rx_pos < link->rx_len);
}

void fscan_serial_get_stats(const struct fscan_serial *link, struct fscan_serial_stats *ret_stats)
{
	if (link && ret_stats)
		*ret_stats = link->stats;
}
