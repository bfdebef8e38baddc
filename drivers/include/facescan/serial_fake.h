/* Back doors of the fake serial transport (fscan_serial_fake_ops). The fake is a connected
 * AF_UNIX stream socket pair: the link reads and writes one end, the test (or an MCU model
 * thread) the other — the "peer". Unplugging closes the pair as a USB unplug would: the link
 * sees a hangup, and reopening fails with -ENODEV until the test plugs it back.
 * Every function takes a handle created with fscan_serial_fake_ops (-EINVAL otherwise).
 */
#ifndef FACESCAN_SERIAL_FAKE_H
#define FACESCAN_SERIAL_FAKE_H

#include "facescan/serial.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The peer's end of the current connection (changes after a replug), or -ENOTCONN. The fake
 * owns it: don't close it. */
int fscan_serial_fake_peer_fd(struct fscan_serial *link);
/* Writes raw bytes as the MCU would send them. Returns len or -errno. */
ssize_t fscan_serial_fake_peer_write(struct fscan_serial *link, const uint8_t *buf, size_t len);
/* Reads raw bytes the link sent, waiting up to timeout_ms. Returns the count or -ETIMEDOUT. */
ssize_t fscan_serial_fake_peer_read(struct fscan_serial *link, uint8_t *buf, size_t cap, int timeout_ms);
/* Encodes `frame` with the protocol's codec and writes it as the peer. */
int fscan_serial_fake_peer_send(struct fscan_serial *link, const struct fs_frame *frame);
/* Reads and decodes the next good frame the link sent (waiting up to timeout_ms). */
int fscan_serial_fake_peer_recv(struct fscan_serial *link, struct fs_frame *ret_frame, int timeout_ms);
/* Simulates pulling the cable: the connection closes, reopen fails with -ENODEV. */
int fscan_serial_fake_unplug(struct fscan_serial *link);
/* Plugs it back: the next reopen succeeds with a fresh connection. */
int fscan_serial_fake_plug(struct fscan_serial *link);
/* How many times the transport was opened (1 after create). */
int fscan_serial_fake_open_count(struct fscan_serial *link);

/* ---- the MCU at the far end ----
 * The real firmware core (firmware/core) on the native board (firmware/boards/native), served
 * by a thread on a descriptor: the fake's peer fd, or the master side of a pty whose slave the
 * termios backend opens. It is the one MCU model of the tests (issue 12): everything it answers
 * is the firmware's own answer (HELLO says board native, firmware FW_VERSION_*, tick 1 MHz).
 * Its virtual clock follows the host's, but a sequence plays to its end at once. It sends
 * EVT_BOOT when started; the thread ends on hangup of its descriptor. The native board is one
 * per process: a second start while one runs fails with -EBUSY.
 * Link with libfacescan-fw-native.a (the Makefile does, for every program and test). */
struct fscan_mcu_model;
/* Starts serving `fd` (not owned: the caller keeps it open until stop). */
int fscan_mcu_model_start(int fd, struct fscan_mcu_model **ret_model);
void fscan_mcu_model_stop(struct fscan_mcu_model *model); /* joins; accepts NULL */
/* Presses the booth button for 3 debounce periods, then releases it (virtual time): the
 * firmware's debouncer counts one press, sends EVT_BUTTON, and when armed runs a scan. */
int fscan_mcu_model_press(struct fscan_mcu_model *model);
/* Mute: bytes from the host are dropped before the firmware's UART (a hung MCU: nothing is
 * answered); the firmware itself keeps running. */
int fscan_mcu_model_set_mute(struct fscan_mcu_model *model, bool mute);
/* Sequences completed (the firmware's STATUS scan count). */
int fscan_mcu_model_scans(struct fscan_mcu_model *model);

/* fscan_serial_fake_ops->open fails with -ENOENT when cfg->device is this name. */
#define FSCAN_SERIAL_FAKE_MISSING_DEVICE "missing"

#ifdef __cplusplus
}
#endif
#endif
