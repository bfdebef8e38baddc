/* Protocol codec: CRC, COBS, frame round trips, the incremental decoder's verdicts and
 * resynchronisation, body helpers. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "protocol/protocol.h"

/* Feeds bytes; returns the number of frames completed, storing the last in *out, and the
 * last negative verdict in *last_err (0 if none). */
static int feed_all(struct fs_decoder *d, const uint8_t *buf, size_t n, struct fs_frame *out,
		    int *last_err)
{
	int frames = 0;
	*last_err = 0;
	for (size_t i = 0; i < n; i++) {
		int r = fs_decoder_feed(d, buf[i], out);
		if (r == 1)
			frames++;
		else if (r < 0)
			*last_err = r;
	}
	return frames;
}

static void test_crc16_check_value(void **state)
{
	(void)state;
	/* The catalogue check value of CRC-16/CCITT-FALSE. */
	assert_int_equal(fs_crc16((const uint8_t *)"123456789", 9), 0x29b1);
	assert_int_equal(fs_crc16(NULL, 0), 0xffff);
}

static void test_cobs_round_trip_and_no_zero(void **state)
{
	(void)state;
	uint8_t in[600], enc[620], dec[600];
	/* Lengths around the 254-byte block boundary, with and without zeros. */
	const size_t lens[] = { 0, 1, 2, 253, 254, 255, 508, 600 };
	for (int pattern = 0; pattern < 3; pattern++) {
		for (size_t li = 0; li < sizeof(lens) / sizeof(lens[0]); li++) {
			size_t n = lens[li];
			for (size_t i = 0; i < n; i++)
				in[i] = pattern == 0 ? 0 : pattern == 1 ? (uint8_t)(i % 255 + 1)
									: (uint8_t)(i * 7);
			int e = fs_cobs_encode(in, n, enc, sizeof(enc));
			assert_true(e > 0);
			assert_true((size_t)e <= n + n / 254 + 1);
			for (int i = 0; i < e; i++)
				assert_int_not_equal(enc[i], 0);
			int d = fs_cobs_decode(enc, (size_t)e, dec, sizeof(dec));
			assert_int_equal(d, (int)n);
			assert_memory_equal(in, dec, n);
		}
	}
}

static void test_cobs_rejects_bad_input(void **state)
{
	(void)state;
	uint8_t out[16];
	const uint8_t overrun[] = { 0x05, 0x11, 0x22 }; /* code promises 4 bytes, 2 follow */
	assert_int_equal(fs_cobs_decode(overrun, sizeof(overrun), out, sizeof(out)), -EILSEQ);
	const uint8_t zero[] = { 0x02, 0x00 };
	assert_int_equal(fs_cobs_decode(zero, sizeof(zero), out, sizeof(out)), -EILSEQ);
	const uint8_t big[] = { 0x04, 1, 2, 3 };
	assert_int_equal(fs_cobs_decode(big, sizeof(big), out, 2), -ENOBUFS);
	uint8_t in[8] = { 1, 2, 3, 4, 5, 6, 7, 8 };
	assert_int_equal(fs_cobs_encode(in, sizeof(in), out, 4), -ENOBUFS);
}

static void test_frame_round_trip_every_length(void **state)
{
	(void)state;
	struct fs_decoder d;
	fs_decoder_init(&d);
	for (unsigned len = 0; len <= FS_PROTO_MAX_BODY; len++) {
		struct fs_frame f, g;
		fs_frame_init(&f, FS_CMD_SET_TIMING, (uint8_t)(len * 3));
		f.len = (uint8_t)len;
		for (unsigned i = 0; i < len; i++)
			f.body[i] = (uint8_t)(i % 3 == 0 ? 0 : i * 13); /* plenty of zeros */
		uint8_t buf[FS_PROTO_MAX_FRAME];
		size_t n = 0;
		assert_int_equal(fs_frame_encode(&f, buf, sizeof(buf), &n), 0);
		assert_true(n <= FS_PROTO_MAX_FRAME);
		assert_int_equal(buf[0], 0);
		assert_int_equal(buf[n - 1], 0);
		for (size_t i = 1; i + 1 < n; i++)
			assert_int_not_equal(buf[i], 0);
		int err;
		assert_int_equal(feed_all(&d, buf, n, &g, &err), 1);
		assert_int_equal(err, 0);
		assert_int_equal(g.version, FS_PROTO_VERSION);
		assert_int_equal(g.type, f.type);
		assert_int_equal(g.seq, f.seq);
		assert_int_equal(g.len, len);
		assert_memory_equal(g.body, f.body, len);
	}
}

static void test_encode_errors(void **state)
{
	(void)state;
	struct fs_frame f;
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t n = 1234;
	fs_frame_init(&f, FS_CMD_HELLO, 1);
	f.len = FS_PROTO_MAX_BODY + 1;
	assert_int_equal(fs_frame_encode(&f, buf, sizeof(buf), &n), -EINVAL);
	f.len = 10;
	assert_int_equal(fs_frame_encode(&f, buf, 8, &n), -ENOBUFS);
	assert_int_equal(n, 1234); /* untouched on failure */
}

static size_t encode(const struct fs_frame *f, uint8_t *buf)
{
	size_t n = 0;
	assert_int_equal(fs_frame_encode(f, buf, FS_PROTO_MAX_FRAME, &n), 0);
	return n;
}

static void test_crc_error_detected_then_recovers(void **state)
{
	(void)state;
	struct fs_frame f, g;
	uint8_t buf[FS_PROTO_MAX_FRAME];
	struct fs_decoder d;
	fs_decoder_init(&d);
	fs_frame_init(&f, FS_CMD_FIRE, 7);
	size_t n = encode(&f, buf);
	/* Flip one bit of every payload byte in turn: each must be caught. */
	for (size_t i = 1; i + 1 < n; i++) {
		uint8_t bad[FS_PROTO_MAX_FRAME];
		memcpy(bad, buf, n);
		bad[i] ^= 0x10;
		if (bad[i] == 0)
			continue; /* became a delimiter: a different (framing) case */
		int err;
		assert_int_equal(feed_all(&d, bad, n, &g, &err), 0);
		assert_true(err == -EBADMSG || err == -EILSEQ || err == -ENOMSG);
	}
	int err;
	assert_int_equal(feed_all(&d, buf, n, &g, &err), 1);
	assert_int_equal(g.type, FS_CMD_FIRE);
	assert_int_equal(fs_err_from_decode(-EBADMSG), FS_ERR_CRC);
}

static void test_truncated_frame(void **state)
{
	(void)state;
	struct fs_decoder d;
	struct fs_frame g;
	fs_decoder_init(&d);
	/* A COBS-valid frame of 3 bytes cannot hold header + CRC. */
	uint8_t raw[3] = { FS_PROTO_VERSION, FS_CMD_HELLO, 1 };
	uint8_t buf[16];
	buf[0] = 0;
	int e = fs_cobs_encode(raw, sizeof(raw), buf + 1, sizeof(buf) - 2);
	assert_true(e > 0);
	buf[1 + e] = 0;
	int err;
	assert_int_equal(feed_all(&d, buf, (size_t)e + 2, &g, &err), 0);
	assert_int_equal(err, -ENOMSG);
	assert_int_equal(fs_err_from_decode(err), FS_ERR_TRUNCATED);

	/* A frame cut short by a lost tail: the next frame's leading 0x00 ends it. */
	struct fs_frame f;
	fs_frame_init(&f, FS_CMD_STATUS, 9);
	uint8_t good[FS_PROTO_MAX_FRAME];
	size_t n = encode(&f, good);
	assert_int_equal(feed_all(&d, good, n - 3, &g, &err), 0);
	assert_int_equal(feed_all(&d, good, n, &g, &err), 1);
	assert_true(err < 0);
	assert_int_equal(g.type, FS_CMD_STATUS);
	assert_int_equal(g.seq, 9);
}

static void test_oversize_frame_dropped(void **state)
{
	(void)state;
	struct fs_decoder d;
	struct fs_frame g;
	fs_decoder_init(&d);
	uint8_t junk[300];
	memset(junk, 0x41, sizeof(junk));
	junk[0] = 0;
	junk[299] = 0;
	int err;
	assert_int_equal(feed_all(&d, junk, sizeof(junk), &g, &err), 0);
	assert_int_equal(err, -EMSGSIZE);
	assert_int_equal(fs_err_from_decode(err), FS_ERR_OVERSIZE);

	/* One byte over the maximum body, encoded by hand with a valid CRC. */
	uint8_t raw[FS_PROTO_MAX_PAYLOAD + 1];
	memset(raw, 0x55, sizeof(raw));
	raw[0] = FS_PROTO_VERSION;
	uint16_t crc = fs_crc16(raw, sizeof(raw) - 2);
	raw[sizeof(raw) - 2] = (uint8_t)crc;
	raw[sizeof(raw) - 1] = (uint8_t)(crc >> 8);
	uint8_t buf[FS_PROTO_MAX_FRAME + 8];
	buf[0] = 0;
	int e = fs_cobs_encode(raw, sizeof(raw), buf + 1, sizeof(buf) - 2);
	assert_true(e > 0);
	buf[1 + e] = 0;
	assert_int_equal(feed_all(&d, buf, (size_t)e + 2, &g, &err), 0);
	assert_int_equal(err, -EMSGSIZE);

	/* And the decoder works right after. */
	struct fs_frame f;
	fs_frame_init(&f, FS_CMD_HELLO, 2);
	uint8_t good[FS_PROTO_MAX_FRAME];
	size_t n = encode(&f, good);
	assert_int_equal(feed_all(&d, good, n, &g, &err), 1);
	assert_int_equal(g.seq, 2);
}

static void test_garbage_then_good_frame(void **state)
{
	(void)state;
	struct fs_decoder d;
	struct fs_frame f, g;
	fs_decoder_init(&d);
	fs_frame_init(&f, FS_CMD_GET_TIMING, 0x42);
	uint8_t stream[200];
	size_t n = 0;
	/* Garbage without any 0x00: only the frame's leading delimiter can cut it off. */
	for (int i = 0; i < 40; i++)
		stream[n++] = (uint8_t)(0x80 | (i * 37));
	n += encode(&f, stream + n);
	/* A lost byte in a second copy, then a third intact copy. */
	size_t m = encode(&f, stream + n);
	memmove(stream + n + 3, stream + n + 4, m - 4);
	n += m - 1;
	n += encode(&f, stream + n);
	int frames = 0, errors = 0;
	for (size_t i = 0; i < n; i++) {
		int r = fs_decoder_feed(&d, stream[i], &g);
		if (r == 1) {
			frames++;
			assert_int_equal(g.type, FS_CMD_GET_TIMING);
			assert_int_equal(g.seq, 0x42);
		} else if (r < 0) {
			errors++;
		}
	}
	assert_int_equal(frames, 2);
	assert_int_equal(errors, 2);
}

static void test_timing_bounds_and_round_trip(void **state)
{
	(void)state;
	struct fs_timing t, u;
	fs_timing_default(&t);
	assert_int_equal(fs_timing_validate(&t), 0);
	struct fs_frame f;
	fs_frame_init(&f, FS_CMD_SET_TIMING, 1);
	t.proj_settle_us = 123456;
	t.flash_hold_us = 4321;
	fs_timing_put(&f, &t);
	assert_int_equal(f.len, FS_TIMING_WIRE_LEN);
	assert_int_equal(fs_timing_get(&f, &u), 0);
	assert_memory_equal(&t, &u, sizeof(t));

	struct {
		uint32_t *field;
		uint32_t lo, hi;
	} cases[] = {
		{ &t.proj_settle_us, FS_TIMING_SETTLE_MIN, FS_TIMING_SETTLE_MAX },
		{ &t.flash_settle_us, FS_TIMING_SETTLE_MIN, FS_TIMING_SETTLE_MAX },
		{ &t.exposure_us, FS_TIMING_EXPOSURE_MIN, FS_TIMING_EXPOSURE_MAX },
		{ &t.flash_exposure_us, FS_TIMING_EXPOSURE_MIN, FS_TIMING_EXPOSURE_MAX },
		{ &t.proj_hold_us, FS_TIMING_HOLD_MIN, FS_TIMING_HOLD_MAX },
		{ &t.flash_hold_us, FS_TIMING_HOLD_MIN, FS_TIMING_HOLD_MAX },
		{ &t.flash_delay_us, FS_TIMING_DELAY_MIN, FS_TIMING_DELAY_MAX },
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		fs_timing_default(&t);
		*cases[i].field = cases[i].lo;
		assert_int_equal(fs_timing_validate(&t), 0);
		*cases[i].field = cases[i].hi;
		assert_int_equal(fs_timing_validate(&t), 0);
		*cases[i].field = cases[i].lo - 1;
		assert_int_equal(fs_timing_validate(&t), -ERANGE);
		*cases[i].field = cases[i].hi + 1;
		assert_int_equal(fs_timing_validate(&t), -ERANGE);
	}
	f.len = FS_TIMING_WIRE_LEN - 1;
	fs_timing_default(&u);
	assert_int_equal(fs_timing_get(&f, &t), -EBADMSG);
}

static void test_body_helpers_round_trip(void **state)
{
	(void)state;
	struct fs_frame f;
	fs_frame_init(&f, FS_EVT_REPORT, 3);

	struct fs_report r = { .result = FS_REPORT_DONE, .trigger = FS_TRIGGER_BUTTON,
			       .scan = 0xbeef, .steps = FS_STEP__COUNT, .lines_end = 0 };
	for (unsigned i = 0; i < FS_STEP__COUNT; i++) {
		r.tick[i] = 0x01020304u * i;
		r.lines[i] = (uint8_t)(0x11 * i);
	}
	struct fs_report r2;
	fs_report_put(&f, &r);
	assert_int_equal(f.len, FS_REPORT_WIRE_LEN);
	assert_true(f.len <= FS_PROTO_MAX_BODY);
	assert_int_equal(fs_report_get(&f, &r2), 0);
	assert_int_equal(r2.scan, 0xbeef);
	assert_int_equal(r2.trigger, FS_TRIGGER_BUTTON);
	assert_memory_equal(r2.tick, r.tick, sizeof(r.tick));
	assert_memory_equal(r2.lines, r.lines, sizeof(r.lines));
	f.body[4] = FS_STEP__COUNT + 1;
	assert_int_equal(fs_report_get(&f, &r2), -EBADMSG);

	struct fs_status s = { FS_STATE_ARMED, FS_FAULT_WATCHDOG, FS_RESET_WATCHDOG, 0x0f,
			       1000, 2000, 3000, 0xdeadbeef }, s2;
	fs_status_put(&f, &s);
	assert_int_equal(fs_status_get(&f, &s2), 0);
	assert_int_equal(s2.state, s.state);
	assert_int_equal(s2.fault, s.fault);
	assert_int_equal(s2.reset_cause, s.reset_cause);
	assert_int_equal(s2.lines, s.lines);
	assert_int_equal(s2.scans, s.scans);
	assert_int_equal(s2.rx_errors, s.rx_errors);
	assert_int_equal(s2.buttons, s.buttons);
	assert_int_equal(s2.uptime_ms, s.uptime_ms);

	struct fs_hello h = { FS_PROTO_VERSION, 1, 2, FS_BOARD_STM32F103, 1000000,
			      FS_PROTO_MAX_BODY }, h2;
	fs_hello_put(&f, &h);
	assert_int_equal(fs_hello_get(&f, &h2), 0);
	assert_int_equal(h2.proto_version, h.proto_version);
	assert_int_equal(h2.fw_major, 1);
	assert_int_equal(h2.fw_minor, 2);
	assert_int_equal(h2.board, FS_BOARD_STM32F103);
	assert_int_equal(h2.tick_hz, 1000000);
	assert_int_equal(h2.max_body, FS_PROTO_MAX_BODY);

	struct fs_nack n = { FS_ERR_RANGE, FS_CMD_SET_TIMING }, n2;
	fs_nack_put(&f, &n);
	assert_int_equal(fs_nack_get(&f, &n2), 0);
	assert_int_equal(n2.err, FS_ERR_RANGE);
	assert_int_equal(n2.cmd, FS_CMD_SET_TIMING);

	struct fs_button b = { 1, 513 }, b2;
	fs_button_put(&f, &b);
	assert_int_equal(fs_button_get(&f, &b2), 0);
	assert_int_equal(b2.count, 513);
	assert_int_equal(fs_nack_get(&f, &n2), -EBADMSG);

	struct fs_boot bo = { FS_RESET_WATCHDOG, FS_PROTO_VERSION }, bo2;
	fs_boot_put(&f, &bo);
	assert_int_equal(fs_boot_get(&f, &bo2), 0);
	assert_int_equal(bo2.reset_cause, FS_RESET_WATCHDOG);

	struct fs_fault x = { FS_FAULT_LIGHT_TIMEOUT, 0 }, x2;
	fs_fault_put(&f, &x);
	assert_int_equal(fs_fault_get(&f, &x2), 0);
	assert_int_equal(x2.code, FS_FAULT_LIGHT_TIMEOUT);

	uint8_t cmd = 0;
	fs_ack_put(&f, FS_CMD_ARM);
	assert_int_equal(fs_ack_get(&f, &cmd), 0);
	assert_int_equal(cmd, FS_CMD_ARM);

	uint16_t hold = 0;
	fs_debug_button_put(&f, 250);
	assert_int_equal(fs_debug_button_get(&f, &hold), 0);
	assert_int_equal(hold, 250);
}

static void test_names_and_classes(void **state)
{
	(void)state;
	assert_string_equal(fs_type_name(FS_CMD_FIRE), "FIRE");
	assert_string_equal(fs_type_name(0x77), "?");
	assert_string_equal(fs_err_name(FS_ERR_CRC), "crc mismatch");
	assert_string_equal(fs_err_name(200), "?");
	assert_true(fs_type_is_command(FS_CMD_HELLO));
	assert_false(fs_type_is_command(FS_RSP_ACK));
	assert_true(fs_type_is_response(FS_RSP_NACK));
	assert_true(fs_type_is_event(FS_EVT_REPORT));
	assert_false(fs_type_is_event(FS_RSP_NACK));
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test(test_crc16_check_value),
		cmocka_unit_test(test_cobs_round_trip_and_no_zero),
		cmocka_unit_test(test_cobs_rejects_bad_input),
		cmocka_unit_test(test_frame_round_trip_every_length),
		cmocka_unit_test(test_encode_errors),
		cmocka_unit_test(test_crc_error_detected_then_recovers),
		cmocka_unit_test(test_truncated_frame),
		cmocka_unit_test(test_oversize_frame_dropped),
		cmocka_unit_test(test_garbage_then_good_frame),
		cmocka_unit_test(test_timing_bounds_and_round_trip),
		cmocka_unit_test(test_body_helpers_round_trip),
		cmocka_unit_test(test_names_and_classes),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
