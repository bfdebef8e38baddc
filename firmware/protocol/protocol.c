/* Codec of the host <-> MCU protocol; see protocol.h for the wire format. */
#include "protocol/protocol.h"

#include <errno.h>
#include <string.h>

uint16_t fs_crc16(const uint8_t *data, size_t len)
{
	uint16_t crc = 0xffffu;
	for (size_t i = 0; i < len; i++) {
		crc ^= (uint16_t)((uint16_t)data[i] << 8);
		for (int b = 0; b < 8; b++)
			crc = (crc & 0x8000u) ? (uint16_t)((crc << 1) ^ 0x1021u) : (uint16_t)(crc << 1);
	}
	return crc;
}

int fs_cobs_encode(const uint8_t *in, size_t len, uint8_t *out, size_t cap)
{
	size_t code_at = 0, o = 1;
	uint8_t code = 1;

	if (cap < 1)
		return -ENOBUFS;
	for (size_t i = 0; i < len; i++) {
		if (in[i] != 0) {
			if (o >= cap)
				return -ENOBUFS;
			out[o++] = in[i];
			code++;
		}
		if (in[i] == 0 || code == 0xff) {
			out[code_at] = code;
			code = 1;
			code_at = o;
			if (o >= cap)
				return -ENOBUFS;
			o++;
		}
	}
	out[code_at] = code;
	return (int)o;
}

int fs_cobs_decode(const uint8_t *in, size_t len, uint8_t *out, size_t cap)
{
	size_t i = 0, o = 0;

	while (i < len) {
		uint8_t code = in[i++];
		if (code == 0)
			return -EILSEQ;
		for (uint8_t k = 1; k < code; k++) {
			if (i >= len || in[i] == 0)
				return -EILSEQ;
			if (o >= cap)
				return -ENOBUFS;
			out[o++] = in[i++];
		}
		/* A zero is implied after every block but the last and after 0xff blocks. */
		if (code != 0xff && i < len) {
			if (o >= cap)
				return -ENOBUFS;
			out[o++] = 0;
		}
	}
	return (int)o;
}

void fs_frame_init(struct fs_frame *f, uint8_t type, uint8_t seq)
{
	f->version = FS_PROTO_VERSION;
	f->type = type;
	f->seq = seq;
	f->len = 0;
}

int fs_frame_encode(const struct fs_frame *f, uint8_t *buf, size_t cap, size_t *ret_len)
{
	uint8_t raw[FS_PROTO_MAX_PAYLOAD];
	size_t n = 0;

	if (f->len > FS_PROTO_MAX_BODY)
		return -EINVAL;
	if (cap < 2)
		return -ENOBUFS;
	raw[n++] = f->version;
	raw[n++] = f->type;
	raw[n++] = f->seq;
	memcpy(&raw[n], f->body, f->len);
	n += f->len;
	uint16_t crc = fs_crc16(raw, n);
	raw[n++] = (uint8_t)(crc & 0xffu);
	raw[n++] = (uint8_t)(crc >> 8);

	buf[0] = 0;
	int r = fs_cobs_encode(raw, n, buf + 1, cap - 2);
	if (r < 0)
		return r;
	buf[1 + (size_t)r] = 0;
	*ret_len = (size_t)r + 2;
	return 0;
}

void fs_decoder_init(struct fs_decoder *d)
{
	d->n = 0;
	d->overflow = false;
}

int fs_decoder_feed(struct fs_decoder *d, uint8_t byte, struct fs_frame *ret_frame)
{
	if (byte != 0) {
		if (d->n < sizeof(d->buf))
			d->buf[d->n++] = byte;
		else
			d->overflow = true;
		return 0;
	}

	/* Delimiter: judge what was collected, then start afresh whatever the verdict. */
	size_t n = d->n;
	bool overflow = d->overflow;
	fs_decoder_init(d);
	if (overflow)
		return -EMSGSIZE;
	if (n == 0)
		return 0;

	uint8_t raw[FS_PROTO_MAX_PAYLOAD];
	int r = fs_cobs_decode(d->buf, n, raw, sizeof(raw));
	if (r == -ENOBUFS)
		return -EMSGSIZE;
	if (r < 0)
		return -EILSEQ;
	size_t len = (size_t)r;
	if (len < FS_PROTO_HDR_LEN + FS_PROTO_CRC_LEN)
		return -ENOMSG;
	uint16_t want = (uint16_t)(raw[len - 2] | (raw[len - 1] << 8));
	if (fs_crc16(raw, len - 2) != want)
		return -EBADMSG;

	ret_frame->version = raw[0];
	ret_frame->type = raw[1];
	ret_frame->seq = raw[2];
	ret_frame->len = (uint8_t)(len - FS_PROTO_HDR_LEN - FS_PROTO_CRC_LEN);
	memcpy(ret_frame->body, &raw[FS_PROTO_HDR_LEN], ret_frame->len);
	return 1;
}

uint8_t fs_err_from_decode(int rc)
{
	switch (rc) {
	case -EMSGSIZE:
		return FS_ERR_OVERSIZE;
	case -ENOMSG:
		return FS_ERR_TRUNCATED;
	case -EBADMSG:
		return FS_ERR_CRC;
	default:
		return FS_ERR_FRAMING;
	}
}

/* ---- little-endian field access ---------------------------------------------------------- */

static void put_u16(uint8_t *p, uint16_t v)
{
	p[0] = (uint8_t)(v & 0xffu);
	p[1] = (uint8_t)(v >> 8);
}

static void put_u32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)(v & 0xffu);
	p[1] = (uint8_t)((v >> 8) & 0xffu);
	p[2] = (uint8_t)((v >> 16) & 0xffu);
	p[3] = (uint8_t)(v >> 24);
}

static uint16_t get_u16(const uint8_t *p)
{
	return (uint16_t)(p[0] | (p[1] << 8));
}

static uint32_t get_u32(const uint8_t *p)
{
	return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) |
	       ((uint32_t)p[3] << 24);
}

/* ---- timing ------------------------------------------------------------------------------ */

void fs_timing_default(struct fs_timing *ret)
{
	ret->proj_settle_us = FS_TIMING_DEFAULT_PROJ_SETTLE;
	ret->exposure_us = FS_TIMING_DEFAULT_EXPOSURE;
	ret->proj_hold_us = FS_TIMING_DEFAULT_PROJ_HOLD;
	ret->flash_delay_us = FS_TIMING_DEFAULT_FLASH_DELAY;
	ret->flash_settle_us = FS_TIMING_DEFAULT_FLASH_SETTLE;
	ret->flash_exposure_us = FS_TIMING_DEFAULT_FLASH_EXPOSURE;
	ret->flash_hold_us = FS_TIMING_DEFAULT_FLASH_HOLD;
}

static bool in_range(uint32_t v, uint32_t lo, uint32_t hi)
{
	return v >= lo && v <= hi;
}

int fs_timing_validate(const struct fs_timing *t)
{
	if (!in_range(t->proj_settle_us, FS_TIMING_SETTLE_MIN, FS_TIMING_SETTLE_MAX) ||
	    !in_range(t->flash_settle_us, FS_TIMING_SETTLE_MIN, FS_TIMING_SETTLE_MAX) ||
	    !in_range(t->exposure_us, FS_TIMING_EXPOSURE_MIN, FS_TIMING_EXPOSURE_MAX) ||
	    !in_range(t->flash_exposure_us, FS_TIMING_EXPOSURE_MIN, FS_TIMING_EXPOSURE_MAX) ||
	    !in_range(t->proj_hold_us, FS_TIMING_HOLD_MIN, FS_TIMING_HOLD_MAX) ||
	    !in_range(t->flash_hold_us, FS_TIMING_HOLD_MIN, FS_TIMING_HOLD_MAX) ||
	    !in_range(t->flash_delay_us, FS_TIMING_DELAY_MIN, FS_TIMING_DELAY_MAX))
		return -ERANGE;
	return 0;
}

void fs_timing_put(struct fs_frame *f, const struct fs_timing *t)
{
	uint8_t *p = f->body;
	put_u32(p + 0, t->proj_settle_us);
	put_u32(p + 4, t->exposure_us);
	put_u32(p + 8, t->proj_hold_us);
	put_u32(p + 12, t->flash_delay_us);
	put_u32(p + 16, t->flash_settle_us);
	put_u32(p + 20, t->flash_exposure_us);
	put_u32(p + 24, t->flash_hold_us);
	f->len = FS_TIMING_WIRE_LEN;
}

int fs_timing_get(const struct fs_frame *f, struct fs_timing *ret)
{
	const uint8_t *p = f->body;
	if (f->len != FS_TIMING_WIRE_LEN)
		return -EBADMSG;
	ret->proj_settle_us = get_u32(p + 0);
	ret->exposure_us = get_u32(p + 4);
	ret->proj_hold_us = get_u32(p + 8);
	ret->flash_delay_us = get_u32(p + 12);
	ret->flash_settle_us = get_u32(p + 16);
	ret->flash_exposure_us = get_u32(p + 20);
	ret->flash_hold_us = get_u32(p + 24);
	return 0;
}

/* ---- other bodies ------------------------------------------------------------------------ */

void fs_hello_put(struct fs_frame *f, const struct fs_hello *h)
{
	uint8_t *p = f->body;
	p[0] = h->proto_version;
	p[1] = h->fw_major;
	p[2] = h->fw_minor;
	p[3] = h->board;
	put_u32(p + 4, h->tick_hz);
	p[8] = h->max_body;
	f->len = FS_HELLO_WIRE_LEN;
}

int fs_hello_get(const struct fs_frame *f, struct fs_hello *ret)
{
	const uint8_t *p = f->body;
	if (f->len != FS_HELLO_WIRE_LEN)
		return -EBADMSG;
	ret->proto_version = p[0];
	ret->fw_major = p[1];
	ret->fw_minor = p[2];
	ret->board = p[3];
	ret->tick_hz = get_u32(p + 4);
	ret->max_body = p[8];
	return 0;
}

void fs_status_put(struct fs_frame *f, const struct fs_status *s)
{
	uint8_t *p = f->body;
	p[0] = s->state;
	p[1] = s->fault;
	p[2] = s->reset_cause;
	p[3] = s->lines;
	put_u16(p + 4, s->scans);
	put_u16(p + 6, s->rx_errors);
	put_u16(p + 8, s->buttons);
	put_u32(p + 10, s->uptime_ms);
	f->len = FS_STATUS_WIRE_LEN;
}

int fs_status_get(const struct fs_frame *f, struct fs_status *ret)
{
	const uint8_t *p = f->body;
	if (f->len != FS_STATUS_WIRE_LEN)
		return -EBADMSG;
	ret->state = p[0];
	ret->fault = p[1];
	ret->reset_cause = p[2];
	ret->lines = p[3];
	ret->scans = get_u16(p + 4);
	ret->rx_errors = get_u16(p + 6);
	ret->buttons = get_u16(p + 8);
	ret->uptime_ms = get_u32(p + 10);
	return 0;
}

void fs_report_put(struct fs_frame *f, const struct fs_report *r)
{
	uint8_t *p = f->body;
	p[0] = r->result;
	p[1] = r->trigger;
	put_u16(p + 2, r->scan);
	p[4] = r->steps;
	p[5] = r->lines_end;
	for (unsigned i = 0; i < FS_STEP__COUNT; i++) {
		put_u32(p + 6 + 4 * i, r->tick[i]);
		p[6 + 4 * FS_STEP__COUNT + i] = r->lines[i];
	}
	f->len = FS_REPORT_WIRE_LEN;
}

int fs_report_get(const struct fs_frame *f, struct fs_report *ret)
{
	const uint8_t *p = f->body;
	if (f->len != FS_REPORT_WIRE_LEN || p[4] > FS_STEP__COUNT)
		return -EBADMSG;
	ret->result = p[0];
	ret->trigger = p[1];
	ret->scan = get_u16(p + 2);
	ret->steps = p[4];
	ret->lines_end = p[5];
	for (unsigned i = 0; i < FS_STEP__COUNT; i++) {
		ret->tick[i] = get_u32(p + 6 + 4 * i);
		ret->lines[i] = p[6 + 4 * FS_STEP__COUNT + i];
	}
	return 0;
}

void fs_nack_put(struct fs_frame *f, const struct fs_nack *n)
{
	f->body[0] = n->err;
	f->body[1] = n->cmd;
	f->len = FS_NACK_WIRE_LEN;
}

int fs_nack_get(const struct fs_frame *f, struct fs_nack *ret)
{
	if (f->len != FS_NACK_WIRE_LEN)
		return -EBADMSG;
	ret->err = f->body[0];
	ret->cmd = f->body[1];
	return 0;
}

void fs_boot_put(struct fs_frame *f, const struct fs_boot *b)
{
	f->body[0] = b->reset_cause;
	f->body[1] = b->proto_version;
	f->len = FS_BOOT_WIRE_LEN;
}

int fs_boot_get(const struct fs_frame *f, struct fs_boot *ret)
{
	if (f->len != FS_BOOT_WIRE_LEN)
		return -EBADMSG;
	ret->reset_cause = f->body[0];
	ret->proto_version = f->body[1];
	return 0;
}

void fs_button_put(struct fs_frame *f, const struct fs_button *b)
{
	f->body[0] = b->started;
	put_u16(f->body + 1, b->count);
	f->len = FS_BUTTON_WIRE_LEN;
}

int fs_button_get(const struct fs_frame *f, struct fs_button *ret)
{
	if (f->len != FS_BUTTON_WIRE_LEN)
		return -EBADMSG;
	ret->started = f->body[0];
	ret->count = get_u16(f->body + 1);
	return 0;
}

void fs_fault_put(struct fs_frame *f, const struct fs_fault *x)
{
	f->body[0] = x->code;
	f->body[1] = x->lines;
	f->len = FS_FAULT_WIRE_LEN;
}

int fs_fault_get(const struct fs_frame *f, struct fs_fault *ret)
{
	if (f->len != FS_FAULT_WIRE_LEN)
		return -EBADMSG;
	ret->code = f->body[0];
	ret->lines = f->body[1];
	return 0;
}

void fs_ack_put(struct fs_frame *f, uint8_t cmd)
{
	f->body[0] = cmd;
	f->len = 1;
}

int fs_ack_get(const struct fs_frame *f, uint8_t *ret_cmd)
{
	if (f->len != 1)
		return -EBADMSG;
	*ret_cmd = f->body[0];
	return 0;
}

void fs_debug_button_put(struct fs_frame *f, uint16_t hold_ms)
{
	put_u16(f->body, hold_ms);
	f->len = 2;
}

int fs_debug_button_get(const struct fs_frame *f, uint16_t *ret_hold_ms)
{
	if (f->len != 2)
		return -EBADMSG;
	*ret_hold_ms = get_u16(f->body);
	return 0;
}

/* ---- names ------------------------------------------------------------------------------- */

const char *fs_type_name(uint8_t type)
{
	switch (type) {
	case FS_CMD_HELLO: return "HELLO";
	case FS_CMD_GET_TIMING: return "GET_TIMING";
	case FS_CMD_SET_TIMING: return "SET_TIMING";
	case FS_CMD_ARM: return "ARM";
	case FS_CMD_DISARM: return "DISARM";
	case FS_CMD_FIRE: return "FIRE";
	case FS_CMD_ABORT: return "ABORT";
	case FS_CMD_STATUS: return "STATUS";
	case FS_CMD_CLEAR_FAULT: return "CLEAR_FAULT";
	case FS_CMD_DEBUG_HANG: return "DEBUG_HANG";
	case FS_CMD_DEBUG_BUTTON: return "DEBUG_BUTTON";
	case FS_RSP_ACK: return "ACK";
	case FS_RSP_HELLO: return "HELLO_REPLY";
	case FS_RSP_TIMING: return "TIMING";
	case FS_RSP_STATUS: return "STATUS_REPLY";
	case FS_RSP_NACK: return "NACK";
	case FS_EVT_BOOT: return "EVT_BOOT";
	case FS_EVT_BUTTON: return "EVT_BUTTON";
	case FS_EVT_REPORT: return "EVT_REPORT";
	case FS_EVT_FAULT: return "EVT_FAULT";
	default: return "?";
	}
}

const char *fs_err_name(uint8_t err)
{
	static const char *const names[FS_ERR__COUNT] = {
		[FS_ERR_NONE] = "none",
		[FS_ERR_CRC] = "crc mismatch",
		[FS_ERR_FRAMING] = "bad framing",
		[FS_ERR_OVERSIZE] = "oversize frame",
		[FS_ERR_TRUNCATED] = "truncated frame",
		[FS_ERR_VERSION] = "protocol version mismatch",
		[FS_ERR_UNKNOWN_CMD] = "unknown command",
		[FS_ERR_LENGTH] = "bad body length",
		[FS_ERR_RANGE] = "value out of range",
		[FS_ERR_BUSY] = "sequence running",
		[FS_ERR_FAULT] = "fault latched",
	};
	return err < FS_ERR__COUNT ? names[err] : "?";
}

bool fs_type_is_command(uint8_t type)
{
	return type >= 0x01 && type <= 0x3f;
}

bool fs_type_is_response(uint8_t type)
{
	return type >= 0x80 && type <= 0xbf;
}

bool fs_type_is_event(uint8_t type)
{
	return type >= 0xc0;
}
