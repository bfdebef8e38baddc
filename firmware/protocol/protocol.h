/*
 * facescan host <-> MCU protocol: the single source of truth shared by the trigger firmware
 * (firmware/core) and the host (drivers/serial, the fuzz target). Portable C11, no allocation,
 * no I/O. Every function returns 0 (or a documented positive value) or a negative errno.
 *
 * Wire format of one frame:
 *
 *     0x00 | COBS( version | type | seq | body[0..FS_PROTO_MAX_BODY] | crc16_lo | crc16_hi ) | 0x00
 *
 * - COBS removes every 0x00 from the payload, so 0x00 only ever delimits frames. The leading
 *   0x00 terminates whatever garbage the receiver may hold, so a good frame after line noise
 *   is never swallowed; empty frames (two 0x00 in a row) are ignored by the decoder.
 * - crc16 is CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over version..body, little-endian.
 * - version is FS_PROTO_VERSION. The firmware answers HELLO whatever the version byte says (so
 *   a host can learn the firmware's version); any other command with a different version is
 *   refused with NACK FS_ERR_VERSION.
 * - seq: the host numbers its commands; every response (ACK, NACK or a reply) echoes the seq
 *   of the command it answers. Events carry the firmware's own event counter, which increments
 *   by one per event, so the host can see a lost event. A NACK for a frame that could not be
 *   decoded (bad CRC, framing, size) has seq 0 and cmd 0: its header could not be trusted.
 * - Multi-byte body fields are little-endian; use the fs_*_put / fs_*_get helpers below rather
 *   than memcpy of structs (no packing or endianness assumptions).
 */
#ifndef FACESCAN_PROTOCOL_H
#define FACESCAN_PROTOCOL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define FS_PROTO_VERSION 1u

#define FS_PROTO_HDR_LEN 3u  /* version, type, seq */
#define FS_PROTO_CRC_LEN 2u
#define FS_PROTO_MAX_BODY 48u
#define FS_PROTO_MAX_PAYLOAD (FS_PROTO_HDR_LEN + FS_PROTO_MAX_BODY + FS_PROTO_CRC_LEN)
/* COBS adds one byte per started 254-byte block; plus the two 0x00 delimiters. */
#define FS_PROTO_MAX_COBS (FS_PROTO_MAX_PAYLOAD + FS_PROTO_MAX_PAYLOAD / 254u + 1u)
#define FS_PROTO_MAX_FRAME (FS_PROTO_MAX_COBS + 2u)

/* ---- message types ---------------------------------------------------------------------
 * 0x01..0x3f commands (host -> MCU), 0x80..0xbf responses (MCU -> host, echo the command's
 * seq), 0xc0..0xff events (MCU -> host, unsolicited, firmware's event seq). */
enum fs_type {
	/* commands */
	FS_CMD_HELLO = 0x01,        /* body: none. reply FS_RSP_HELLO */
	FS_CMD_GET_TIMING = 0x02,   /* body: none. reply FS_RSP_TIMING */
	FS_CMD_SET_TIMING = 0x03,   /* body: struct fs_timing. ACK, or NACK FS_ERR_RANGE */
	FS_CMD_ARM = 0x04,          /* body: none. ACK; the booth button may now start a scan */
	FS_CMD_DISARM = 0x05,       /* body: none. ACK; back to idle (button only reported) */
	FS_CMD_FIRE = 0x06,         /* body: none. ACK, then EVT_REPORT when the sequence ends */
	FS_CMD_ABORT = 0x07,        /* body: none. lights off at once, ACK (+ EVT_REPORT aborted) */
	FS_CMD_STATUS = 0x08,       /* body: none. reply FS_RSP_STATUS */
	FS_CMD_CLEAR_FAULT = 0x09,  /* body: none. ACK; leaves the fault state for idle */
	FS_CMD_DEBUG_HANG = 0x3d,   /* body: none. emulated boards only (else NACK UNKNOWN): ACK,
	                               then the main loop stops working (and kicking the watchdog)
	                               as if stuck, to exercise the watchdog path */
	FS_CMD_DEBUG_BUTTON = 0x3e, /* body: u16 hold_ms. emulated boards only (else NACK UNKNOWN):
	                               holds the button input low for hold_ms through the debounce */

	/* responses */
	FS_RSP_ACK = 0x80,    /* body: u8 cmd */
	FS_RSP_HELLO = 0x81,  /* body: struct fs_hello */
	FS_RSP_TIMING = 0x82, /* body: struct fs_timing */
	FS_RSP_STATUS = 0x88, /* body: struct fs_status */
	FS_RSP_NACK = 0xbf,   /* body: struct fs_nack */

	/* events */
	FS_EVT_BOOT = 0xc0,   /* body: struct fs_boot. sent once after every reset */
	FS_EVT_BUTTON = 0xc1, /* body: struct fs_button. a debounced press */
	FS_EVT_REPORT = 0xc2, /* body: struct fs_report. a sequence ended (done/aborted/fault) */
	FS_EVT_FAULT = 0xc3,  /* body: struct fs_fault. lights were forced off */
};

/* ---- error codes carried in NACK (wire values, stable) --------------------------------- */
enum fs_err {
	FS_ERR_NONE = 0,
	FS_ERR_CRC = 1,         /* checksum mismatch */
	FS_ERR_FRAMING = 2,     /* invalid COBS */
	FS_ERR_OVERSIZE = 3,    /* frame longer than FS_PROTO_MAX_FRAME */
	FS_ERR_TRUNCATED = 4,   /* shorter than header + CRC */
	FS_ERR_VERSION = 5,     /* header version != FS_PROTO_VERSION */
	FS_ERR_UNKNOWN_CMD = 6, /* type is not a command this firmware knows */
	FS_ERR_LENGTH = 7,      /* body length wrong for this command */
	FS_ERR_RANGE = 8,       /* a timing value outside its bounds */
	FS_ERR_BUSY = 9,        /* a sequence is running */
	FS_ERR_FAULT = 10,      /* firmware is in the fault state: CLEAR_FAULT first */
	FS_ERR__COUNT
};

/* ---- lines driven by the firmware (bit masks, shared by core, boards and host) ---------- */
#define FS_LINE_PROJ1 (1u << 0)
#define FS_LINE_PROJ2 (1u << 1)
#define FS_LINE_PROJ3 (1u << 2)
#define FS_LINE_FLASH (1u << 3)
#define FS_LINE_SHUT1 (1u << 4)
#define FS_LINE_SHUT2 (1u << 5)
#define FS_LINE_SHUT3 (1u << 6)
#define FS_LINE_SHUT4 (1u << 7)
#define FS_LINES_PROJ (FS_LINE_PROJ1 | FS_LINE_PROJ2 | FS_LINE_PROJ3)
#define FS_LINES_LIGHT (FS_LINES_PROJ | FS_LINE_FLASH)
#define FS_LINES_SHUT (FS_LINE_SHUT1 | FS_LINE_SHUT2 | FS_LINE_SHUT3 | FS_LINE_SHUT4)

/* ---- payload structures ---------------------------------------------------------------- */

/* Sequence timing in microseconds. The sequence, from t=0:
 *   projectors on -> proj_settle -> shutters rise -> exposure -> shutters fall
 *   -> proj_hold -> projectors off -> flash_delay -> flash on -> flash_settle -> shutters rise
 *   -> flash_exposure -> shutters fall -> flash_hold -> flash off
 * Bounds in FS_TIMING_* below; the firmware refuses anything outside with FS_ERR_RANGE. */
struct fs_timing {
	uint32_t proj_settle_us;
	uint32_t exposure_us;
	uint32_t proj_hold_us;
	uint32_t flash_delay_us;
	uint32_t flash_settle_us;
	uint32_t flash_exposure_us;
	uint32_t flash_hold_us;
};
#define FS_TIMING_WIRE_LEN 28u

/* Defaults and bounds (inclusive), microseconds. */
#define FS_TIMING_DEFAULT_PROJ_SETTLE 20000u
#define FS_TIMING_DEFAULT_EXPOSURE 8000u
#define FS_TIMING_DEFAULT_PROJ_HOLD 100u
#define FS_TIMING_DEFAULT_FLASH_DELAY 16000u
#define FS_TIMING_DEFAULT_FLASH_SETTLE 500u
#define FS_TIMING_DEFAULT_FLASH_EXPOSURE 2000u
#define FS_TIMING_DEFAULT_FLASH_HOLD 100u
#define FS_TIMING_SETTLE_MIN 100u
#define FS_TIMING_SETTLE_MAX 500000u     /* proj_settle, flash_settle */
#define FS_TIMING_EXPOSURE_MIN 50u
#define FS_TIMING_EXPOSURE_MAX 100000u   /* exposure, flash_exposure */
#define FS_TIMING_HOLD_MIN 10u
#define FS_TIMING_HOLD_MAX 10000u        /* proj_hold, flash_hold */
#define FS_TIMING_DELAY_MIN 100u
#define FS_TIMING_DELAY_MAX 500000u      /* flash_delay */

/* Board identifiers reported in HELLO. */
enum fs_board {
	FS_BOARD_NATIVE = 1,
	FS_BOARD_LM3S6965EVB = 2, /* QEMU */
	FS_BOARD_STM32F103 = 3,
};

struct fs_hello {
	uint8_t proto_version;
	uint8_t fw_major;
	uint8_t fw_minor;
	uint8_t board;      /* enum fs_board */
	uint32_t tick_hz;   /* unit of every timestamp in reports */
	uint8_t max_body;   /* FS_PROTO_MAX_BODY of the firmware */
};
#define FS_HELLO_WIRE_LEN 9u

enum fs_state {
	FS_STATE_IDLE = 0,
	FS_STATE_ARMED = 1,
	FS_STATE_BUSY = 2,
	FS_STATE_FAULT = 3,
};

enum fs_reset_cause {
	FS_RESET_POWER = 0,
	FS_RESET_WATCHDOG = 1,
	FS_RESET_SOFTWARE = 2,
	FS_RESET_PIN = 3,
	FS_RESET_OTHER = 4,
};

enum fs_fault_code {
	FS_FAULT_NONE = 0,
	FS_FAULT_WATCHDOG = 1,     /* the last reset was a watchdog reset: a hung loop recovered */
	FS_FAULT_LIGHT_TIMEOUT = 2,/* lights on longer than FS_LIGHT_MAX_MS: forced off */
	FS_FAULT_OVERRUN = 3,      /* a timer step ran late (missed compare): sequence stopped */
	FS_FAULT_HAL = 4,          /* a board reported an error */
};

/* No light may stay on longer than this, whatever the timing (checked in the main loop). */
#define FS_LIGHT_MAX_MS 1500u

struct fs_status {
	uint8_t state;        /* enum fs_state */
	uint8_t fault;        /* enum fs_fault_code, latched until CLEAR_FAULT */
	uint8_t reset_cause;  /* enum fs_reset_cause */
	uint8_t lines;        /* current FS_LINE_* output levels */
	uint16_t scans;       /* sequences completed since reset */
	uint16_t rx_errors;   /* frames rejected since reset */
	uint16_t buttons;     /* debounced presses since reset */
	uint32_t uptime_ms;
};
#define FS_STATUS_WIRE_LEN 14u

enum fs_report_result {
	FS_REPORT_DONE = 0,
	FS_REPORT_ABORTED = 1,
	FS_REPORT_FAULT = 2,
};

enum fs_trigger {
	FS_TRIGGER_HOST = 0,
	FS_TRIGGER_BUTTON = 1,
};

/* The 8 steps of a sequence, in order; each is one write of the output port. */
enum fs_step {
	FS_STEP_PROJ_ON = 0,
	FS_STEP_SHUT1_RISE = 1,
	FS_STEP_SHUT1_FALL = 2,
	FS_STEP_PROJ_OFF = 3,
	FS_STEP_FLASH_ON = 4,
	FS_STEP_SHUT2_RISE = 5,
	FS_STEP_SHUT2_FALL = 6,
	FS_STEP_FLASH_OFF = 7,
	FS_STEP__COUNT = 8
};

struct fs_report {
	uint8_t result;   /* enum fs_report_result */
	uint8_t trigger;  /* enum fs_trigger */
	uint16_t scan;    /* sequence number since reset (1-based) */
	uint8_t steps;    /* steps executed, 0..FS_STEP__COUNT */
	uint8_t lines_end;/* output levels after the sequence (must have no FS_LINES_LIGHT) */
	uint32_t tick[FS_STEP__COUNT];  /* tick of each executed step, relative to step 0 */
	uint8_t lines[FS_STEP__COUNT];  /* output levels right after each step */
};
#define FS_REPORT_WIRE_LEN 46u

struct fs_nack {
	uint8_t err;  /* enum fs_err */
	uint8_t cmd;  /* the refused command's type, 0 if the frame was undecodable */
};
#define FS_NACK_WIRE_LEN 2u

struct fs_boot {
	uint8_t reset_cause;  /* enum fs_reset_cause */
	uint8_t proto_version;
};
#define FS_BOOT_WIRE_LEN 2u

struct fs_button {
	uint8_t started;   /* 1: the press started a scan (state was ARMED) */
	uint16_t count;    /* presses since reset */
};
#define FS_BUTTON_WIRE_LEN 3u

struct fs_fault {
	uint8_t code;      /* enum fs_fault_code */
	uint8_t lines;     /* output levels after the forced lights-off */
};
#define FS_FAULT_WIRE_LEN 2u

/* One decoded (or to-be-encoded) frame. */
struct fs_frame {
	uint8_t version;
	uint8_t type;
	uint8_t seq;
	uint8_t len;  /* body length, 0..FS_PROTO_MAX_BODY */
	uint8_t body[FS_PROTO_MAX_BODY];
};

/* ---- framing --------------------------------------------------------------------------- */

/* CRC-16/CCITT-FALSE. */
uint16_t fs_crc16(const uint8_t *data, size_t len);

/* COBS-encode len bytes into out (no delimiters). Returns the encoded length (>0), or
 * -ENOBUFS if cap is too small. out must not overlap in. */
int fs_cobs_encode(const uint8_t *in, size_t len, uint8_t *out, size_t cap);
/* COBS-decode (input without delimiters, no 0x00 inside). Returns the decoded length,
 * -EILSEQ on invalid encoding, -ENOBUFS if cap is too small. */
int fs_cobs_decode(const uint8_t *in, size_t len, uint8_t *out, size_t cap);

/* Initialise a frame: current version, no body. */
void fs_frame_init(struct fs_frame *f, uint8_t type, uint8_t seq);

/* Encode f (including both delimiters) into buf. On success stores the byte count in
 * *ret_len and returns 0. -EINVAL if f->len > FS_PROTO_MAX_BODY, -ENOBUFS if cap is smaller
 * than needed (FS_PROTO_MAX_FRAME always suffices). */
int fs_frame_encode(const struct fs_frame *f, uint8_t *buf, size_t cap, size_t *ret_len);

/* Incremental decoder: feed it the received bytes one at a time. Holds no pointers; may be
 * copied or reset by fs_decoder_init at any time. */
struct fs_decoder {
	uint8_t buf[FS_PROTO_MAX_COBS];
	uint16_t n;
	bool overflow;
};

void fs_decoder_init(struct fs_decoder *d);

/* Feed one byte. Returns:
 *   0          need more bytes (ret_frame untouched)
 *   1          a valid frame was completed and stored in *ret_frame
 *   -EMSGSIZE  an oversize frame was dropped          (FS_ERR_OVERSIZE)
 *   -EILSEQ    a frame with invalid COBS was dropped  (FS_ERR_FRAMING)
 *   -ENOMSG    a frame too short to hold header + CRC (FS_ERR_TRUNCATED)
 *   -EBADMSG   a frame with a CRC mismatch was dropped (FS_ERR_CRC)
 * After an error the decoder is already resynchronised: the next 0x00 starts a new frame.
 * The version byte is not checked here (see the top of this file). */
int fs_decoder_feed(struct fs_decoder *d, uint8_t byte, struct fs_frame *ret_frame);

/* Map a negative fs_decoder_feed result to the NACK error code (FS_ERR_FRAMING otherwise). */
uint8_t fs_err_from_decode(int rc);

/* ---- body helpers ------------------------------------------------------------------------
 * *_put fills f->body and f->len (type and seq are the caller's). *_get checks f->len against
 * the wire length and returns -EBADMSG on mismatch, leaving *ret untouched. */
void fs_timing_default(struct fs_timing *ret);
/* 0 if every field is within its bounds, else -ERANGE. */
int fs_timing_validate(const struct fs_timing *t);

void fs_timing_put(struct fs_frame *f, const struct fs_timing *t);
int fs_timing_get(const struct fs_frame *f, struct fs_timing *ret);
void fs_hello_put(struct fs_frame *f, const struct fs_hello *h);
int fs_hello_get(const struct fs_frame *f, struct fs_hello *ret);
void fs_status_put(struct fs_frame *f, const struct fs_status *s);
int fs_status_get(const struct fs_frame *f, struct fs_status *ret);
void fs_report_put(struct fs_frame *f, const struct fs_report *r);
int fs_report_get(const struct fs_frame *f, struct fs_report *ret);
void fs_nack_put(struct fs_frame *f, const struct fs_nack *n);
int fs_nack_get(const struct fs_frame *f, struct fs_nack *ret);
void fs_boot_put(struct fs_frame *f, const struct fs_boot *b);
int fs_boot_get(const struct fs_frame *f, struct fs_boot *ret);
void fs_button_put(struct fs_frame *f, const struct fs_button *b);
int fs_button_get(const struct fs_frame *f, struct fs_button *ret);
void fs_fault_put(struct fs_frame *f, const struct fs_fault *x);
int fs_fault_get(const struct fs_frame *f, struct fs_fault *ret);
/* ACK body: the acknowledged command's type. */
void fs_ack_put(struct fs_frame *f, uint8_t cmd);
int fs_ack_get(const struct fs_frame *f, uint8_t *ret_cmd);
/* DEBUG_BUTTON body: hold time in ms. */
void fs_debug_button_put(struct fs_frame *f, uint16_t hold_ms);
int fs_debug_button_get(const struct fs_frame *f, uint16_t *ret_hold_ms);

/* Human-readable names for logs ("?" when unknown). Never NULL. */
const char *fs_type_name(uint8_t type);
const char *fs_err_name(uint8_t err);

/* true for 0x01..0x3f, 0x80..0xbf, 0xc0..0xff respectively. */
bool fs_type_is_command(uint8_t type);
bool fs_type_is_response(uint8_t type);
bool fs_type_is_event(uint8_t type);

#ifdef __cplusplus
}
#endif

#endif
