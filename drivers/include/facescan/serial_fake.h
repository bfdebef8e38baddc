/* Back doors of the fake serial transport (fscan_serial_fake_ops). The fake is a connected
 * AF_UNIX stream socket pair: the link reads and writes one end, the test (or an MCU model
 * thread) the other — the "peer". Unplugging closes the pair as a USB unplug would: the link
 * sees a hangup, and reopening fails with -ENODEV until the test plugs it back.
 * The functions that take a link need one created with fscan_serial_fake_ops (-EINVAL
 * otherwise).
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
/* The cable is pulled during the next sequence: once the firmware has started it (lights on),
 * the model shuts its descriptor down both ways (the host reads what was sent, then a hangup;
 * the report never comes) and stops serving. The descriptor must be a socket (the fake's
 * peer): -ENOTSOCK otherwise. */
int fscan_mcu_model_hangup_on_sequence(struct fscan_mcu_model *model);
/* 1 once the model has hung up that way, else 0. */
int fscan_mcu_model_hung_up(struct fscan_mcu_model *model);

/* ---- a fake device with the MCU on it (facescand's serial_device = fake) ----
 * These take the device's name (cfg->device), not a link: a test reaches the MCU while another
 * part owns the link (facescand's SerialMcu destroys and recreates its link on a hangup).
 * -EINVAL when no device of that name has the MCU attached. */
/* Attaches the MCU model to `device`: every connection a link opens to it from now on is served
 * by the model on the peer end. The MCU is powered by its cable: each connection boots the
 * firmware (EVT_BOOT first), and the model stops when the link closes or the cable is pulled.
 * The device stays registered, plugged in, and the scan count starts from 0.
 * -EBUSY while a link has it open, -ENOMEM when the registry is full. */
int fscan_serial_fake_attach_mcu(const char *device);
/* Pulls the cable (the MCU stops, the link sees a hangup, reopening fails with -ENODEV) and
 * plugs it back. */
int fscan_serial_fake_device_unplug(const char *device);
int fscan_serial_fake_device_plug(const char *device);
/* Presses the MCU's booth button (fscan_mcu_model_press). -ENOTCONN when no link is connected. */
int fscan_serial_fake_mcu_press(const char *device);
/* The link is lost during the next sequence (fscan_mcu_model_hangup_on_sequence): the link sees
 * a hangup instead of the report, and the device stays unplugged until
 * fscan_serial_fake_device_plug(). -ENOTCONN when no link is connected. */
int fscan_serial_fake_mcu_unplug_on_fire(const char *device);
/* Sequences the firmware completed since the attach, over every connection. */
int fscan_serial_fake_mcu_scans(const char *device);

/* fscan_serial_fake_ops->open fails with -ENOENT when cfg->device is this name. */
#define FSCAN_SERIAL_FAKE_MISSING_DEVICE "missing"

#ifdef __cplusplus
}
#endif
#endif
