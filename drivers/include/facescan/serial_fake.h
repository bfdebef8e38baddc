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

/* ---- an in-process MCU model ----
 * A thread that speaks the firmware protocol on a descriptor: the fake's peer fd, or the master
 * side of a pty whose slave the termios backend opens. It answers HELLO (board native, version
 * 0.1, tick 1 MHz), GET/SET_TIMING (with the protocol's bounds), ARM, DISARM, FIRE (ACK, then
 * EVT_REPORT done with the 8 steps at the configured timing), ABORT, STATUS, CLEAR_FAULT, and
 * NACKs the rest as the firmware would. It sends EVT_BOOT when started. The thread ends on
 * hangup of its descriptor. */
struct fscan_mcu_model;
/* Starts serving `fd` (not owned: the caller keeps it open until stop). */
int fscan_mcu_model_start(int fd, struct fscan_mcu_model **ret_model);
void fscan_mcu_model_stop(struct fscan_mcu_model *model); /* joins; accepts NULL */
/* A debounced booth press: EVT_BUTTON, and when armed a scan (EVT_REPORT, trigger button). */
int fscan_mcu_model_press(struct fscan_mcu_model *model);
/* Mute: the model reads but answers nothing (a hung MCU). */
int fscan_mcu_model_set_mute(struct fscan_mcu_model *model, bool mute);
/* Sends EVT_FAULT with `code` (enum fs_fault_code) and enters the fault state. */
int fscan_mcu_model_fault(struct fscan_mcu_model *model, uint8_t code);
/* Commands received (good frames), and sequences fired. */
int fscan_mcu_model_commands(struct fscan_mcu_model *model);
int fscan_mcu_model_scans(struct fscan_mcu_model *model);

/* fscan_serial_fake_ops->open fails with -ENOENT when cfg->device is this name. */
#define FSCAN_SERIAL_FAKE_MISSING_DEVICE "missing"

#ifdef __cplusplus
}
#endif
#endif
