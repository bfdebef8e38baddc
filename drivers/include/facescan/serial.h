/* facescan serial driver: the link to the trigger MCU.
 *
 * Two layers in one handle:
 *   - a byte transport (the ops table): termios on a tty, or the fake (an in-memory socket pair
 *     whose far end a test or an MCU model drives, see facescan/serial_fake.h);
 *   - the firmware protocol on top (common code, serial.c) with the protocol's own codec
 *     (firmware/protocol/protocol.h: COBS + CRC-16 frames, struct fs_frame). Corrupt frames are
 *     counted and skipped; the decoder resynchronises on the next delimiter.
 *
 * Unplug: when the transport reports a hangup (USB serial unplugged: POLLHUP, EIO, ENXIO) the
 * link goes down and the call returns -ENOTCONN. Every later call first tries to reopen the
 * device once; while that fails it returns -ENOTCONN at once. After a reopen the MCU must be
 * greeted again (stats.reconnects tells a caller that it happened).
 *
 * Every function returns 0 (or a count) or a negative errno; nothing here logs or exits.
 * One thread per handle.
 */
#ifndef FACESCAN_SERIAL_H
#define FACESCAN_SERIAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "protocol/protocol.h"

#ifdef __cplusplus
extern "C" {
#endif

struct fscan_serial_config {
	const char *device;  /* "/dev/ttyACM0", a pty slave path; fake: any name */
	unsigned baud;       /* 9600 .. 4000000, one of the termios rates; 0 = 115200 */
};

/* The byte transport a backend provides. */
struct fscan_serial_ops {
	const char *name;
	/* Opens the device in raw mode (8N1, no flow control, no echo, no line discipline).
	 * -ENOENT/-ENODEV no device, -EACCES, -EBUSY, -EINVAL unsupported baud, -ENOTTY not a tty. */
	int (*open)(const struct fscan_serial_config *cfg, void **ret_ctx);
	void (*close)(void *ctx);
	/* Reads what is there (at least 1 byte): returns the count, -ETIMEDOUT when nothing came
	 * within timeout_ms (0 = poll, <0 = forever), -ENOTCONN on hangup, -EINTR, -EIO. */
	ssize_t (*read)(void *ctx, uint8_t *buf, size_t cap, int timeout_ms);
	/* Writes all of buf (polling for room in between): returns len, -ETIMEDOUT,
	 * -ENOTCONN on hangup, -EIO. */
	ssize_t (*write)(void *ctx, const uint8_t *buf, size_t len, int timeout_ms);
	/* The pollable descriptor. */
	int (*fd)(void *ctx);
};

extern const struct fscan_serial_ops fscan_serial_termios_ops;
extern const struct fscan_serial_ops fscan_serial_fake_ops;

struct fscan_serial_stats {
	uint64_t frames_rx;      /* good frames received */
	uint64_t frames_tx;
	uint64_t bad_frames;     /* CRC, COBS, short or oversize frames: skipped */
	uint64_t events_dropped; /* events lost because the queue was full */
	uint64_t reconnects;     /* successful reopens after a hangup */
	uint64_t hangups;        /* times the link went down */
};

struct fscan_serial;

/* Opens the device. On success *ret_link must be freed with fscan_serial_destroy().
 * -EINVAL for NULL arguments, else what ops->open returns. */
int fscan_serial_create(const struct fscan_serial_ops *ops, const struct fscan_serial_config *cfg,
			struct fscan_serial **ret_link);
void fscan_serial_destroy(struct fscan_serial *link); /* accepts NULL */

/* ---- frame level ---- */

/* Sends one frame as is (the caller sets type, seq, body). 0, -EINVAL bad frame, -ENOTCONN,
 * -ETIMEDOUT, -EIO. */
int fscan_serial_send(struct fscan_serial *link, const struct fs_frame *frame, int timeout_ms);
/* Receives the next good frame of any type (events queued by fscan_serial_request() first).
 * 0, -ETIMEDOUT when none completed within timeout_ms, -ENOTCONN, -EIO, -EINTR. */
int fscan_serial_recv(struct fscan_serial *link, struct fs_frame *ret_frame, int timeout_ms);

/* ---- request level (the firmware protocol's command/response rule) ---- */

/* Sends command `cmd` (its seq is assigned here: *cmd is updated) and waits for the response
 * echoing that seq. Events that arrive meanwhile are queued for fscan_serial_next_event();
 * stale responses (other seqs) are dropped.
 * Returns 0 with *ret_resp (may be NULL) = ACK or the reply, -EREMOTEIO when the MCU answered
 * NACK (*ret_resp holds it: fs_nack_get() tells why), -ETIMEDOUT, -ENOTCONN, -EIO. */
int fscan_serial_request(struct fscan_serial *link, struct fs_frame *cmd, struct fs_frame *ret_resp,
			 int timeout_ms);
/* The next event (FS_EVT_*): queued ones first, then from the wire (responses that arrive
 * here are stale and dropped). 0, -ETIMEDOUT, -ENOTCONN, -EIO. */
int fscan_serial_next_event(struct fscan_serial *link, struct fs_frame *ret_event, int timeout_ms);

/* Thin wrappers over fscan_serial_request() for each command; same returns. */
int fscan_serial_hello(struct fscan_serial *link, struct fs_hello *ret_hello, int timeout_ms);
int fscan_serial_get_timing(struct fscan_serial *link, struct fs_timing *ret_timing, int timeout_ms);
int fscan_serial_set_timing(struct fscan_serial *link, const struct fs_timing *timing, int timeout_ms);
int fscan_serial_status(struct fscan_serial *link, struct fs_status *ret_status, int timeout_ms);
/* FS_CMD_ARM, DISARM, FIRE, ABORT, CLEAR_FAULT: commands answered by a plain ACK. */
int fscan_serial_command(struct fscan_serial *link, uint8_t type, int timeout_ms);
/* The last NACK's error code (enum fs_err), FS_ERR_NONE if the last request was not refused. */
uint8_t fscan_serial_last_nack(const struct fscan_serial *link);

/* ---- link state ---- */

/* Drops whatever was received but not yet read, and the event queue. */
void fscan_serial_flush_input(struct fscan_serial *link);
/* Closes and reopens the device now (after an MCU reset, say). 0 or what ops->open returns. */
int fscan_serial_reconnect(struct fscan_serial *link);
bool fscan_serial_connected(const struct fscan_serial *link);
/* The transport's pollable fd, or -ENOTCONN while the link is down. */
int fscan_serial_fd(const struct fscan_serial *link);
/* True when received bytes or queued events wait in the handle (poll() on the fd would not
 * say so): call fscan_serial_recv()/next_event() with timeout 0 before polling again. */
bool fscan_serial_pending(const struct fscan_serial *link);
void fscan_serial_get_stats(const struct fscan_serial *link, struct fscan_serial_stats *ret_stats);

#ifdef __cplusplus
}
#endif
#endif
