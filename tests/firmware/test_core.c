/* The firmware core on the native board: sequence order and widths, commands and NACKs,
 * debounce, watchdog path, lights-off on fault/abort/reset, LED patterns. Time is virtual
 * (1 MHz); the tests inject UART bytes and button levels and read the line-change log. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include <cmocka.h>

#include "boards/native/native.h"
#include "core/debounce.h"
#include "core/fw.h"
#include "core/led.h"
#include "core/sequence.h"
#include "hal.h"
#include "protocol/protocol.h"

#define MAX_RX 32

static struct fs_decoder host_dec;

/* Run the main loop for `us` microseconds of virtual time, polling every 50 us. */
static void run_us(uint64_t us)
{
	while (us > 0) {
		uint64_t step = us < 50 ? us : 50;
		native_advance(step);
		fw_core_poll();
		us -= step;
	}
}

/* Decode everything the firmware sent since the last call. */
static int take_frames(struct fs_frame *out, int max)
{
	uint8_t buf[4096];
	int n = 0;
	size_t len = native_uart_take(buf, sizeof(buf));
	for (size_t i = 0; i < len; i++) {
		struct fs_frame f;
		int r = fs_decoder_feed(&host_dec, buf[i], &f);
		assert_true(r >= 0); /* the firmware never sends a bad frame */
		if (r == 1 && n < max)
			out[n++] = f;
	}
	return n;
}

static void send_frame(const struct fs_frame *f)
{
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t n = 0;
	assert_int_equal(fs_frame_encode(f, buf, sizeof(buf), &n), 0);
	native_uart_inject(buf, n);
}

static void send_cmd(uint8_t type, uint8_t seq)
{
	struct fs_frame f;
	fs_frame_init(&f, type, seq);
	send_frame(&f);
}

/* Send a command, run 1 ms, and return the one response (events may precede it). */
static struct fs_frame transact(const struct fs_frame *cmd)
{
	struct fs_frame rx[MAX_RX];
	send_frame(cmd);
	run_us(1000);
	int n = take_frames(rx, MAX_RX);
	for (int i = 0; i < n; i++)
		if (fs_type_is_response(rx[i].type)) {
			assert_int_equal(rx[i].seq, cmd->seq);
			return rx[i];
		}
	fail_msg("no response to %s", fs_type_name(cmd->type));
	return rx[0];
}

static struct fs_frame transact_cmd(uint8_t type, uint8_t seq)
{
	struct fs_frame f;
	fs_frame_init(&f, type, seq);
	return transact(&f);
}

static void expect_ack(const struct fs_frame *r, uint8_t cmd)
{
	uint8_t acked = 0;
	assert_int_equal(r->type, FS_RSP_ACK);
	assert_int_equal(fs_ack_get(r, &acked), 0);
	assert_int_equal(acked, cmd);
}

static void expect_nack(const struct fs_frame *r, uint8_t err)
{
	struct fs_nack n;
	assert_int_equal(r->type, FS_RSP_NACK);
	assert_int_equal(fs_nack_get(r, &n), 0);
	assert_int_equal(n.err, err);
}

static struct fs_status status(void)
{
	struct fs_status s;
	struct fs_frame r = transact_cmd(FS_CMD_STATUS, 200);
	assert_int_equal(r.type, FS_RSP_STATUS);
	assert_int_equal(fs_status_get(&r, &s), 0);
	return s;
}

static int boot(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	native_reset(FS_RESET_POWER);
	native_set_debug_inputs(false);
	native_set_isr_latency(0);
	fs_decoder_init(&host_dec);
	fw_core_init();
	assert_int_equal(take_frames(rx, MAX_RX), 1);
	assert_int_equal(rx[0].type, FS_EVT_BOOT);
	native_clear_edges();
	return 0;
}

/* Find the first event of a type among frames. */
static const struct fs_frame *find(const struct fs_frame *rx, int n, uint8_t type)
{
	for (int i = 0; i < n; i++)
		if (rx[i].type == type)
			return &rx[i];
	return NULL;
}

/* ---- tests ------------------------------------------------------------------------------- */

static void test_hello(void **state)
{
	(void)state;
	struct fs_hello h;
	struct fs_frame r = transact_cmd(FS_CMD_HELLO, 1);
	assert_int_equal(r.type, FS_RSP_HELLO);
	assert_int_equal(fs_hello_get(&r, &h), 0);
	assert_int_equal(h.proto_version, FS_PROTO_VERSION);
	assert_int_equal(h.board, FS_BOARD_NATIVE);
	assert_int_equal(h.tick_hz, NATIVE_TICK_HZ);
	assert_int_equal(h.max_body, FS_PROTO_MAX_BODY);

	/* HELLO is answered whatever the version byte, so a host can learn ours. */
	struct fs_frame f;
	fs_frame_init(&f, FS_CMD_HELLO, 2);
	f.version = FS_PROTO_VERSION + 1;
	r = transact(&f);
	assert_int_equal(r.type, FS_RSP_HELLO);
}

/* Fire with `t`, check the line log and the report against the plan. */
static void fire_and_check(const struct fs_timing *t)
{
	struct fs_frame rx[MAX_RX];
	const uint32_t w[FS_STEP__COUNT] = { 0, t->proj_settle_us, t->exposure_us,
					     t->proj_hold_us, t->flash_delay_us,
					     t->flash_settle_us, t->flash_exposure_us,
					     t->flash_hold_us };
	/* Levels after each step: P on, S on, S off, P off, F on, S on, S off, F off. */
	const uint8_t after[FS_STEP__COUNT] = {
		FS_LINES_PROJ, FS_LINES_PROJ | FS_LINES_SHUT, FS_LINES_PROJ, 0,
		FS_LINE_FLASH, FS_LINE_FLASH | FS_LINES_SHUT, FS_LINE_FLASH, 0,
	};
	uint32_t total = 0;
	for (int i = 0; i < FS_STEP__COUNT; i++)
		total += w[i];

	native_clear_edges();
	struct fs_frame r = transact_cmd(FS_CMD_FIRE, 10);
	expect_ack(&r, FS_CMD_FIRE);
	run_us(total + 2000);

	/* Exactly 8 writes, each one edge, at the planned offsets (1 tick = 1 us here). */
	const struct native_edge *e;
	size_t n = native_edges(&e);
	assert_int_equal(n, FS_STEP__COUNT);
	uint32_t at = 0;
	for (size_t i = 0; i < n; i++) {
		at += w[i];
		assert_int_equal(e[i].tick - e[0].tick, at);
		assert_int_equal(e[i].after, after[i]);
	}
	/* All four shutters move in one write, both up and down, both times. */
	assert_int_equal(e[FS_STEP_SHUT1_RISE].before ^ e[FS_STEP_SHUT1_RISE].after, FS_LINES_SHUT);
	assert_int_equal(e[FS_STEP_SHUT1_FALL].before ^ e[FS_STEP_SHUT1_FALL].after, FS_LINES_SHUT);
	assert_int_equal(e[FS_STEP_SHUT2_RISE].before ^ e[FS_STEP_SHUT2_RISE].after, FS_LINES_SHUT);
	assert_int_equal(e[FS_STEP_SHUT2_FALL].before ^ e[FS_STEP_SHUT2_FALL].after, FS_LINES_SHUT);
	assert_int_equal(hal_lines_read(), 0);

	int m = take_frames(rx, MAX_RX);
	const struct fs_frame *rep = find(rx, m, FS_EVT_REPORT);
	assert_non_null(rep);
	struct fs_report rr;
	assert_int_equal(fs_report_get(rep, &rr), 0);
	assert_int_equal(rr.result, FS_REPORT_DONE);
	assert_int_equal(rr.trigger, FS_TRIGGER_HOST);
	assert_int_equal(rr.steps, FS_STEP__COUNT);
	assert_int_equal(rr.lines_end, 0);
	for (int i = 0; i < FS_STEP__COUNT; i++) {
		/* Reported ticks are relative to the scheduled start; the first step is on time. */
		assert_int_equal(rr.tick[i] - rr.tick[0], (uint32_t)(e[i].tick - e[0].tick));
		assert_int_equal(rr.lines[i], after[i]);
	}
	assert_int_equal(rr.tick[0], 0);
}

static void test_default_sequence_order_and_widths(void **state)
{
	(void)state;
	struct fs_timing t;
	fs_timing_default(&t);
	struct fs_frame r = transact_cmd(FS_CMD_GET_TIMING, 3);
	struct fs_timing got;
	assert_int_equal(r.type, FS_RSP_TIMING);
	assert_int_equal(fs_timing_get(&r, &got), 0);
	assert_memory_equal(&got, &t, sizeof(t));
	fire_and_check(&t);
	assert_int_equal(status().scans, 1);
	assert_int_equal(status().state, FS_STATE_IDLE);
}

static void test_configured_sequence_widths(void **state)
{
	(void)state;
	struct fs_timing t = { .proj_settle_us = 1234, .exposure_us = 567, .proj_hold_us = 89,
			       .flash_delay_us = 3000, .flash_settle_us = 222,
			       .flash_exposure_us = 4444, .flash_hold_us = 10 };
	struct fs_frame f;
	fs_frame_init(&f, FS_CMD_SET_TIMING, 4);
	fs_timing_put(&f, &t);
	struct fs_frame r = transact(&f);
	expect_ack(&r, FS_CMD_SET_TIMING);
	r = transact_cmd(FS_CMD_GET_TIMING, 5);
	struct fs_timing got;
	assert_int_equal(fs_timing_get(&r, &got), 0);
	assert_memory_equal(&got, &t, sizeof(t));
	fire_and_check(&t);
	fire_and_check(&t); /* and again: the plan is reusable */
}

static void test_out_of_range_timing_refused(void **state)
{
	(void)state;
	struct fs_timing t;
	fs_timing_default(&t);
	t.exposure_us = FS_TIMING_EXPOSURE_MAX + 1;
	struct fs_frame f;
	fs_frame_init(&f, FS_CMD_SET_TIMING, 6);
	fs_timing_put(&f, &t);
	struct fs_frame r = transact(&f);
	expect_nack(&r, FS_ERR_RANGE);

	struct fs_timing got, def;
	fs_timing_default(&def);
	r = transact_cmd(FS_CMD_GET_TIMING, 7);
	assert_int_equal(fs_timing_get(&r, &got), 0);
	assert_memory_equal(&got, &def, sizeof(def));
}

static void test_malformed_frames_nacked_state_unchanged(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX], r;
	transact_cmd(FS_CMD_ARM, 1);
	struct fs_status before = status();
	assert_int_equal(before.state, FS_STATE_ARMED);

	/* Bad CRC. */
	struct fs_frame f;
	fs_frame_init(&f, FS_CMD_FIRE, 8);
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t n = 0;
	assert_int_equal(fs_frame_encode(&f, buf, sizeof(buf), &n), 0);
	buf[3] ^= 0x01;
	native_uart_inject(buf, n);
	run_us(1000);
	assert_int_equal(take_frames(rx, MAX_RX), 1);
	expect_nack(&rx[0], FS_ERR_CRC);
	assert_int_equal(rx[0].seq, 0);

	/* Unknown command, a response type sent as a command, wrong body length, version. */
	r = transact_cmd(0x3a, 9);
	expect_nack(&r, FS_ERR_UNKNOWN_CMD);
	r = transact_cmd(FS_RSP_ACK, 10);
	expect_nack(&r, FS_ERR_UNKNOWN_CMD);
	fs_frame_init(&f, FS_CMD_FIRE, 11);
	f.len = 3;
	r = transact(&f);
	expect_nack(&r, FS_ERR_LENGTH);
	fs_frame_init(&f, FS_CMD_SET_TIMING, 12);
	f.len = FS_TIMING_WIRE_LEN - 1;
	r = transact(&f);
	expect_nack(&r, FS_ERR_LENGTH);
	fs_frame_init(&f, FS_CMD_FIRE, 13);
	f.version = FS_PROTO_VERSION + 1;
	r = transact(&f);
	expect_nack(&r, FS_ERR_VERSION);
	fs_frame_init(&f, FS_CMD_DEBUG_BUTTON, 14); /* not allowed on this (real) setup */
	fs_debug_button_put(&f, 100);
	r = transact(&f);
	expect_nack(&r, FS_ERR_UNKNOWN_CMD);

	/* Oversize, then garbage followed by a good frame. */
	uint8_t big[200];
	memset(big, 0x33, sizeof(big));
	big[0] = 0;
	big[199] = 0;
	native_uart_inject(big, sizeof(big));
	uint8_t junk[] = { 0x12, 0x99, 0x07, 0xfe };
	native_uart_inject(junk, sizeof(junk));
	send_cmd(FS_CMD_HELLO, 15);
	run_us(1000);
	int m = take_frames(rx, MAX_RX);
	assert_int_equal(m, 3);
	expect_nack(&rx[0], FS_ERR_OVERSIZE);
	assert_int_equal(rx[1].type, FS_RSP_NACK); /* the garbage, cut by the frame's 0x00 */
	assert_int_equal(rx[2].type, FS_RSP_HELLO);
	assert_int_equal(rx[2].seq, 15);

	/* Nothing fired, nothing changed but the error count. */
	assert_int_equal(native_edges(&(const struct native_edge *){ NULL }), 0);
	struct fs_status after = status();
	assert_int_equal(after.state, FS_STATE_ARMED);
	assert_int_equal(after.scans, before.scans);
	assert_int_equal(after.lines, 0);
	assert_int_equal(after.rx_errors, before.rx_errors + 3);
}

static void test_busy_refuses_fire_and_timing(void **state)
{
	(void)state;
	struct fs_frame r = transact_cmd(FS_CMD_FIRE, 1);
	expect_ack(&r, FS_CMD_FIRE);
	r = transact_cmd(FS_CMD_FIRE, 2);
	expect_nack(&r, FS_ERR_BUSY);
	r = transact_cmd(FS_CMD_ARM, 3);
	expect_nack(&r, FS_ERR_BUSY);
	struct fs_frame f;
	struct fs_timing t;
	fs_timing_default(&t);
	fs_frame_init(&f, FS_CMD_SET_TIMING, 4);
	fs_timing_put(&f, &t);
	r = transact(&f);
	expect_nack(&r, FS_ERR_BUSY);
	assert_int_equal(status().state, FS_STATE_BUSY);
}

static void test_abort_mid_sequence_lights_off(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	transact_cmd(FS_CMD_FIRE, 1);
	run_us(FS_TIMING_DEFAULT_PROJ_SETTLE + FS_TIMING_DEFAULT_EXPOSURE / 2);
	assert_int_equal(hal_lines_read(), FS_LINES_PROJ | FS_LINES_SHUT);
	take_frames(rx, MAX_RX);

	send_cmd(FS_CMD_ABORT, 2);
	native_advance(1);
	fw_core_poll();
	assert_int_equal(hal_lines_read(), 0);
	int n = take_frames(rx, MAX_RX);
	assert_int_equal(n, 2);
	expect_ack(&rx[0], FS_CMD_ABORT);
	struct fs_report rep;
	assert_int_equal(rx[1].type, FS_EVT_REPORT);
	assert_int_equal(fs_report_get(&rx[1], &rep), 0);
	assert_int_equal(rep.result, FS_REPORT_ABORTED);
	assert_int_equal(rep.steps, 2);
	assert_int_equal(rep.lines_end, 0);

	/* The timer stays quiet afterwards: no more edges. */
	native_clear_edges();
	run_us(100000);
	assert_int_equal(native_edges(&(const struct native_edge *){ NULL }), 0);
	assert_int_equal(status().state, FS_STATE_IDLE);
}

static void test_debounce_unit(void **state)
{
	(void)state;
	struct fw_debounce d;
	fw_debounce_init(&d, 20, 0);
	/* Bounces of 5 ms never count. */
	uint32_t t = 0;
	for (int i = 0; i < 10; i++, t += 5)
		assert_false(fw_debounce_update(&d, i % 2 == 0, t));
	/* Stable for 19 ms: not yet; at 20 ms: one press; holding: no repeat. */
	int presses = 0;
	uint32_t start = t;
	for (; t < start + 19; t++)
		presses += fw_debounce_update(&d, true, t);
	assert_int_equal(presses, 0);
	for (; t < start + 200; t++)
		presses += fw_debounce_update(&d, true, t);
	assert_int_equal(presses, 1);
	/* Release (debounced), press again: a second press. */
	for (; t < start + 300; t++)
		presses += fw_debounce_update(&d, false, t);
	for (; t < start + 400; t++)
		presses += fw_debounce_update(&d, true, t);
	assert_int_equal(presses, 2);
}

static void press(uint32_t ms)
{
	native_set_button(true);
	run_us((uint64_t)ms * 1000u);
	native_set_button(false);
	run_us(50000);
}

static void test_button_idle_reports_only(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	/* A 5 ms glitch is ignored. */
	press(5);
	assert_int_equal(take_frames(rx, MAX_RX), 0);
	press(60);
	int n = take_frames(rx, MAX_RX);
	assert_int_equal(n, 1);
	struct fs_button b;
	assert_int_equal(rx[0].type, FS_EVT_BUTTON);
	assert_int_equal(fs_button_get(&rx[0], &b), 0);
	assert_int_equal(b.started, 0);
	assert_int_equal(b.count, 1);
	assert_int_equal(native_edges(&(const struct native_edge *){ NULL }), 0);
	assert_int_equal(status().buttons, 1);
}

static void test_button_when_armed_starts_scan(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	struct fs_frame r = transact_cmd(FS_CMD_ARM, 1);
	expect_ack(&r, FS_CMD_ARM);
	press(30);
	run_us(100000);
	int n = take_frames(rx, MAX_RX);
	const struct fs_frame *bf = find(rx, n, FS_EVT_BUTTON);
	const struct fs_frame *rf = find(rx, n, FS_EVT_REPORT);
	assert_non_null(bf);
	assert_non_null(rf);
	assert_true(bf < rf); /* the press is reported before the scan's report */
	assert_int_equal(rf->seq, (uint8_t)(bf->seq + 1)); /* event seq counts up by one */
	struct fs_button b;
	struct fs_report rep;
	assert_int_equal(fs_button_get(bf, &b), 0);
	assert_int_equal(b.started, 1);
	assert_int_equal(fs_report_get(rf, &rep), 0);
	assert_int_equal(rep.trigger, FS_TRIGGER_BUTTON);
	assert_int_equal(rep.result, FS_REPORT_DONE);
	assert_int_equal(native_edges(&(const struct native_edge *){ NULL }), FS_STEP__COUNT);
	/* A scan disarms: the next press only reports. */
	assert_int_equal(status().state, FS_STATE_IDLE);
}

static void test_debug_button_on_emulated_board(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	native_set_debug_inputs(true);
	transact_cmd(FS_CMD_ARM, 1);
	struct fs_frame f;
	fs_frame_init(&f, FS_CMD_DEBUG_BUTTON, 2);
	fs_debug_button_put(&f, 10); /* shorter than the debounce: ignored */
	struct fs_frame r = transact(&f);
	expect_ack(&r, FS_CMD_DEBUG_BUTTON);
	run_us(50000);
	assert_null(find(rx, take_frames(rx, MAX_RX), FS_EVT_BUTTON));
	fs_frame_init(&f, FS_CMD_DEBUG_BUTTON, 3);
	fs_debug_button_put(&f, 40);
	transact(&f);
	run_us(100000);
	int n = take_frames(rx, MAX_RX);
	assert_non_null(find(rx, n, FS_EVT_BUTTON));
	assert_non_null(find(rx, n, FS_EVT_REPORT));
	native_set_debug_inputs(false);
}

static void test_watchdog_recovers_hung_loop(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	/* A healthy loop keeps the watchdog fed. */
	run_us(2000000);
	assert_false(native_wdt_expired());

	/* The loop hangs mid-sequence with the projectors on. */
	transact_cmd(FS_CMD_FIRE, 1);
	run_us(5000);
	assert_int_equal(hal_lines_read(), FS_LINES_PROJ);
	native_advance((FW_WDT_TIMEOUT_MS - 1) * 1000u);
	assert_false(native_wdt_expired());
	native_advance(2000);
	assert_true(native_wdt_expired());

	/* The watchdog resets the MCU: the core comes up dark, in FAULT, and says why. */
	take_frames(rx, MAX_RX);
	native_reset(FS_RESET_WATCHDOG);
	hal_lines_write(FS_LINES_LIGHT, 0); /* whatever the pins did, init must clear them */
	fw_core_init();
	assert_int_equal(hal_lines_read(), 0);
	int n = take_frames(rx, MAX_RX);
	assert_int_equal(n, 2);
	struct fs_boot b;
	struct fs_fault x;
	assert_int_equal(rx[0].type, FS_EVT_BOOT);
	assert_int_equal(fs_boot_get(&rx[0], &b), 0);
	assert_int_equal(b.reset_cause, FS_RESET_WATCHDOG);
	assert_int_equal(rx[1].type, FS_EVT_FAULT);
	assert_int_equal(fs_fault_get(&rx[1], &x), 0);
	assert_int_equal(x.code, FS_FAULT_WATCHDOG);
	assert_int_equal(x.lines, 0);

	struct fs_status s = status();
	assert_int_equal(s.state, FS_STATE_FAULT);
	assert_int_equal(s.reset_cause, FS_RESET_WATCHDOG);
	struct fs_frame r = transact_cmd(FS_CMD_FIRE, 2);
	expect_nack(&r, FS_ERR_FAULT);
	r = transact_cmd(FS_CMD_CLEAR_FAULT, 3);
	expect_ack(&r, FS_CMD_CLEAR_FAULT);
	assert_int_equal(status().fault, FS_FAULT_NONE);
	struct fs_timing t;
	fs_timing_default(&t);
	fire_and_check(&t);
}

static void test_debug_hang_stops_the_loop(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	struct fs_frame r = transact_cmd(FS_CMD_DEBUG_HANG, 1);
	expect_nack(&r, FS_ERR_UNKNOWN_CMD); /* not on a real board */
	native_set_debug_inputs(true);
	r = transact_cmd(FS_CMD_DEBUG_HANG, 2);
	expect_ack(&r, FS_CMD_DEBUG_HANG);
	/* Nothing is answered any more and the watchdog is starved. */
	send_cmd(FS_CMD_HELLO, 3);
	run_us((FW_WDT_TIMEOUT_MS + 10) * 1000u);
	assert_int_equal(take_frames(rx, MAX_RX), 0);
	assert_true(native_wdt_expired());
	native_reset(FS_RESET_WATCHDOG);
	fw_core_init();
	assert_int_equal(status().state, FS_STATE_FAULT);
	native_set_debug_inputs(false);
}

static void test_stuck_light_forced_off(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	/* A light comes on outside any sequence (a stuck driver, a stray write). */
	hal_lines_write(FS_LINE_FLASH, 0);
	run_us((FS_LIGHT_MAX_MS - 10) * 1000u);
	assert_int_equal(hal_lines_read(), FS_LINE_FLASH);
	run_us(20000);
	assert_int_equal(hal_lines_read(), 0);
	int n = take_frames(rx, MAX_RX);
	const struct fs_frame *ff = find(rx, n, FS_EVT_FAULT);
	assert_non_null(ff);
	struct fs_fault x;
	assert_int_equal(fs_fault_get(ff, &x), 0);
	assert_int_equal(x.code, FS_FAULT_LIGHT_TIMEOUT);
	assert_int_equal(x.lines, 0);
	assert_int_equal(status().state, FS_STATE_FAULT);
}

static void test_late_timer_faults_lights_off(void **state)
{
	(void)state;
	struct fs_frame rx[MAX_RX];
	native_set_isr_latency(30); /* > 10 us allowance */
	send_cmd(FS_CMD_FIRE, 1);
	run_us(100000);
	assert_int_equal(hal_lines_read(), 0);
	const struct native_edge *e;
	size_t edges = native_edges(&e);
	assert_int_equal(edges, 2); /* projectors on (late) then everything off */
	assert_int_equal(e[1].after, 0);
	int n = take_frames(rx, MAX_RX);
	const struct fs_frame *ff = find(rx, n, FS_EVT_FAULT);
	const struct fs_frame *rf = find(rx, n, FS_EVT_REPORT);
	assert_non_null(ff);
	assert_non_null(rf);
	struct fs_fault x;
	struct fs_report rep;
	assert_int_equal(fs_fault_get(ff, &x), 0);
	assert_int_equal(x.code, FS_FAULT_OVERRUN);
	assert_int_equal(fs_report_get(rf, &rep), 0);
	assert_int_equal(rep.result, FS_REPORT_FAULT);
	assert_int_equal(rep.steps, 1);
	assert_int_equal(rep.tick[0], 30);
	native_set_isr_latency(0);
}

static void test_abort_in_fault_keeps_fault_and_dark(void **state)
{
	(void)state;
	hal_lines_write(FS_LINE_PROJ2, 0);
	run_us((FS_LIGHT_MAX_MS + 10) * 1000u);
	assert_int_equal(status().state, FS_STATE_FAULT);
	struct fs_frame r = transact_cmd(FS_CMD_ABORT, 1);
	expect_ack(&r, FS_CMD_ABORT);
	assert_int_equal(status().state, FS_STATE_FAULT);
	r = transact_cmd(FS_CMD_ARM, 2);
	expect_nack(&r, FS_ERR_FAULT);
	r = transact_cmd(FS_CMD_DISARM, 3);
	expect_ack(&r, FS_CMD_DISARM);
	assert_int_equal(hal_lines_read(), 0);
}

static void test_led_patterns(void **state)
{
	(void)state;
	/* Steady on when armed; one short flash per 2 s when idle; 10 Hz busy; double flash. */
	for (uint32_t t = 0; t < 4000; t += 7)
		assert_true(fw_led_pattern(FS_STATE_ARMED, t));
	int on = 0;
	for (uint32_t t = 0; t < 2000; t++)
		on += fw_led_pattern(FS_STATE_IDLE, t);
	assert_int_equal(on, 100);
	int edges = 0;
	for (uint32_t t = 1; t < 1000; t++)
		edges += fw_led_pattern(FS_STATE_BUSY, t) != fw_led_pattern(FS_STATE_BUSY, t - 1);
	assert_int_equal(edges, 19);
	edges = 0;
	on = 0;
	for (uint32_t t = 1; t < 1000; t++) {
		edges += fw_led_pattern(FS_STATE_FAULT, t) && !fw_led_pattern(FS_STATE_FAULT, t - 1);
		on += fw_led_pattern(FS_STATE_FAULT, t);
	}
	assert_int_equal(edges, 1); /* the rise at 200 ms; the one at 0 ms is before t=1 */
	assert_int_equal(on, 199);

	/* The board LED follows the state. */
	transact_cmd(FS_CMD_ARM, 1);
	assert_true(native_led());
	transact_cmd(FS_CMD_DISARM, 2);
	run_us(500000 - (native_now() % 2000000u) + 2000000u);
	assert_false(native_led());
}

static void test_sequence_plan_limits(void **state)
{
	(void)state;
	struct fw_seq s;
	struct fs_timing t;
	fs_timing_default(&t);
	assert_int_equal(fw_seq_plan(&s, &t, 1000000), 0);
	assert_int_equal(s.step[FS_STEP_SHUT1_RISE].at, FS_TIMING_DEFAULT_PROJ_SETTLE);
	assert_int_equal(s.step[FS_STEP_SHUT1_RISE].set, FS_LINES_SHUT);
	/* 10 us hold at 50 kHz rounds to 1 tick: fine; at 40 kHz to 0 ticks: refused. */
	t.proj_hold_us = 10;
	t.flash_hold_us = 10;
	assert_int_equal(fw_seq_plan(&s, &t, 100000), 0);
	assert_int_equal(fw_seq_plan(&s, &t, 40000), -ERANGE);
	assert_int_equal(fw_us_to_ticks(15, 100000), 2);
	assert_int_equal(fw_us_to_ticks(14, 100000), 1);
	assert_int_equal(fw_us_to_ticks(FS_TIMING_DELAY_MAX, 72000000), 36000000u);
}

int main(void)
{
	const struct CMUnitTest tests[] = {
		cmocka_unit_test_setup(test_hello, boot),
		cmocka_unit_test_setup(test_default_sequence_order_and_widths, boot),
		cmocka_unit_test_setup(test_configured_sequence_widths, boot),
		cmocka_unit_test_setup(test_out_of_range_timing_refused, boot),
		cmocka_unit_test_setup(test_malformed_frames_nacked_state_unchanged, boot),
		cmocka_unit_test_setup(test_busy_refuses_fire_and_timing, boot),
		cmocka_unit_test_setup(test_abort_mid_sequence_lights_off, boot),
		cmocka_unit_test(test_debounce_unit),
		cmocka_unit_test_setup(test_button_idle_reports_only, boot),
		cmocka_unit_test_setup(test_button_when_armed_starts_scan, boot),
		cmocka_unit_test_setup(test_debug_button_on_emulated_board, boot),
		cmocka_unit_test_setup(test_watchdog_recovers_hung_loop, boot),
		cmocka_unit_test_setup(test_debug_hang_stops_the_loop, boot),
		cmocka_unit_test_setup(test_stuck_light_forced_off, boot),
		cmocka_unit_test_setup(test_late_timer_faults_lights_off, boot),
		cmocka_unit_test_setup(test_abort_in_fault_keeps_fault_and_dark, boot),
		cmocka_unit_test_setup(test_led_patterns, boot),
		cmocka_unit_test(test_sequence_plan_limits),
	};
	return cmocka_run_group_tests(tests, NULL, NULL);
}
