/*
 * libFuzzer target (make fuzz): the protocol decoder and the firmware's command handler.
 *
 * Input byte 0 picks a mode:
 *   odd   the rest is a raw UART byte stream (garbage, partial frames, anything)
 *   even  the rest is records [type][seq][len|0x80=bad version][body...][gap], each encoded
 *         as a valid frame, so the fuzzer reaches every command's handler past the CRC
 * Either way the bytes go to (1) a host-side decoder, whose frames must re-encode to the
 * same frame, and (2) the firmware core on the native board with virtual time running,
 * which must only ever send valid frames and never leave a light on outside a sequence.
 *
 * FS_FUZZ_SEEDS=DIR writes a seed corpus (one frame per command) into DIR at start-up.
 */
#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "boards/native/native.h"
#include "core/fw.h"
#include "hal.h"
#include "protocol/protocol.h"

#define CHECK(cond)                                                                      \
	do {                                                                             \
		if (!(cond)) {                                                           \
			fprintf(stderr, "invariant failed: %s (%s:%d)\n", #cond, __FILE__, \
				__LINE__);                                               \
			abort();                                                         \
		}                                                                        \
	} while (0)

static struct fs_decoder host_dec;  /* decodes the input stream, host side */
static struct fs_decoder reply_dec; /* decodes what the firmware sends */

static void check_replies(void)
{
	uint8_t buf[4096];
	size_t n;
	while ((n = native_uart_take(buf, sizeof(buf))) > 0) {
		for (size_t i = 0; i < n; i++) {
			struct fs_frame f;
			int r = fs_decoder_feed(&reply_dec, buf[i], &f);
			CHECK(r >= 0);
			if (r == 1) {
				CHECK(f.version == FS_PROTO_VERSION);
				CHECK(fs_type_is_response(f.type) || fs_type_is_event(f.type));
				CHECK(strcmp(fs_type_name(f.type), "?") != 0);
			}
		}
	}
}

static void poll_and_check(uint32_t us)
{
	native_advance(us);
	if (native_wdt_expired()) {
		/* DEBUG_HANG starved the watchdog: the MCU resets. */
		native_reset(FS_RESET_WATCHDOG);
		native_set_debug_inputs(true);
		fw_core_init();
	}
	fw_core_poll();
	struct fs_status s;
	fw_core_status(&s);
	CHECK(s.state <= FS_STATE_FAULT);
	if (s.state != FS_STATE_BUSY)
		CHECK((s.lines & FS_LINES_LIGHT) == 0);
	check_replies();
}

static void feed(const uint8_t *p, size_t n)
{
	for (size_t i = 0; i < n; i++) {
		struct fs_frame f, g;
		int r = fs_decoder_feed(&host_dec, p[i], &f);
		CHECK(r == 0 || r == 1 || r == -EMSGSIZE || r == -EILSEQ || r == -ENOMSG || r == -EBADMSG);
		if (r == 1) {
			/* Round trip: what decodes must encode back to a frame that decodes equal. */
			uint8_t buf[FS_PROTO_MAX_FRAME];
			size_t len = 0;
			struct fs_decoder d;
			fs_decoder_init(&d);
			CHECK(f.len <= FS_PROTO_MAX_BODY);
			CHECK(fs_frame_encode(&f, buf, sizeof(buf), &len) == 0);
			int got = 0;
			for (size_t k = 0; k < len; k++)
				if (fs_decoder_feed(&d, buf[k], &g) == 1)
					got++;
			CHECK(got == 1);
			CHECK(g.version == f.version && g.type == f.type && g.seq == f.seq);
			CHECK(g.len == f.len && memcmp(g.body, f.body, f.len) == 0);
		}
	}
	native_uart_inject(p, n);
}

static void write_seeds(const char *dir)
{
	static const uint8_t cmds[] = { FS_CMD_HELLO, FS_CMD_GET_TIMING, FS_CMD_SET_TIMING,
					FS_CMD_ARM, FS_CMD_DISARM, FS_CMD_FIRE, FS_CMD_ABORT,
					FS_CMD_STATUS, FS_CMD_CLEAR_FAULT, FS_CMD_DEBUG_BUTTON,
					FS_CMD_DEBUG_HANG };
	for (size_t i = 0; i < sizeof(cmds); i++) {
		uint8_t rec[2 + 2 + 1 + FS_TIMING_WIRE_LEN + 1];
		size_t n = 0;
		struct fs_frame f;
		fs_frame_init(&f, cmds[i], (uint8_t)i);
		if (cmds[i] == FS_CMD_SET_TIMING) {
			struct fs_timing t;
			fs_timing_default(&t);
			fs_timing_put(&f, &t);
		} else if (cmds[i] == FS_CMD_DEBUG_BUTTON) {
			fs_debug_button_put(&f, 50);
		}
		rec[n++] = 0; /* structured mode */
		rec[n++] = f.type;
		rec[n++] = f.seq;
		rec[n++] = f.len;
		memcpy(rec + n, f.body, f.len);
		n += f.len;
		rec[n++] = 200; /* 20 ms gap */
		char path[512];
		snprintf(path, sizeof(path), "%s/seed-%02x", dir, cmds[i]);
		FILE *o = fopen(path, "wb");
		if (o) {
			fwrite(rec, 1, n, o);
			fclose(o);
		}
		/* And the same frame as raw wire bytes. */
		uint8_t wire[1 + FS_PROTO_MAX_FRAME];
		size_t len = 0;
		wire[0] = 1;
		if (fs_frame_encode(&f, wire + 1, sizeof(wire) - 1, &len) == 0) {
			snprintf(path, sizeof(path), "%s/seed-raw-%02x", dir, cmds[i]);
			o = fopen(path, "wb");
			if (o) {
				fwrite(wire, 1, len + 1, o);
				fclose(o);
			}
		}
	}
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
	(void)argc;
	(void)argv;
	const char *dir = getenv("FS_FUZZ_SEEDS");
	if (dir)
		write_seeds(dir);
	return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (size < 1)
		return 0;
	native_reset(FS_RESET_POWER);
	native_set_debug_inputs(true);
	fs_decoder_init(&host_dec);
	fs_decoder_init(&reply_dec);
	fw_core_init();
	check_replies();

	const uint8_t *p = data + 1;
	size_t n = size - 1;
	if (data[0] & 1) {
		while (n > 0) {
			size_t chunk = n < 16 ? n : 16;
			feed(p, chunk);
			p += chunk;
			n -= chunk;
			poll_and_check(1000);
		}
	} else {
		while (n >= 3) {
			struct fs_frame f;
			fs_frame_init(&f, p[0], p[1]);
			if (p[2] & 0x80)
				f.version = FS_PROTO_VERSION + 1;
			size_t len = p[2] & 0x3fu;
			p += 3;
			n -= 3;
			if (len > n)
				len = n;
			if (len > FS_PROTO_MAX_BODY)
				len = FS_PROTO_MAX_BODY;
			memcpy(f.body, p, len);
			f.len = (uint8_t)len;
			p += len;
			n -= len;
			uint8_t buf[FS_PROTO_MAX_FRAME];
			size_t wl = 0;
			CHECK(fs_frame_encode(&f, buf, sizeof(buf), &wl) == 0);
			feed(buf, wl);
			uint32_t gap = 1;
			if (n > 0) {
				gap = p[0] + 1u;
				p++;
				n--;
			}
			for (uint32_t i = 0; i < gap; i++)
				poll_and_check(100);
		}
	}
	/* Let any sequence run out (or a hung loop reset), then abort: everything ends dark. */
	for (int i = 0; i < 100; i++)
		poll_and_check(10000);
	struct fs_frame f;
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t wl = 0;
	fs_frame_init(&f, FS_CMD_ABORT, 0);
	CHECK(fs_frame_encode(&f, buf, sizeof(buf), &wl) == 0);
	native_uart_inject(buf, wl);
	poll_and_check(100);
	CHECK(hal_lines_read() == 0);
	return 0;
}
