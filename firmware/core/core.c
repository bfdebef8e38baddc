/* The main-loop task: commands, sequence start/finish, button, LED, watchdog, light safety. */
#include "core/fw.h"

#include <string.h>

#include "core/debounce.h"
#include "core/led.h"
#include "core/sequence.h"
#include "hal.h"

/* Single-producer (UART interrupt) single-consumer (main loop) byte ring. The 8-bit indices
 * wrap with the 256-byte buffer, and each side writes only its own index. */
_Static_assert(FW_RX_RING == 256u, "ring indices are uint8_t");
static volatile uint8_t rx_buf[FW_RX_RING];
static volatile uint8_t rx_head; /* written by the interrupt */
static volatile uint8_t rx_tail; /* written by the main loop */
static volatile uint16_t rx_dropped;

static struct {
	uint8_t state;
	uint8_t fault;
	uint8_t reset_cause;
	uint8_t trigger;
	uint8_t evt_seq;
	uint16_t scans;
	uint16_t rx_errors;
	uint16_t buttons;
	uint16_t rx_dropped_seen;
	struct fs_timing timing;
	struct fw_seq seq;
	struct fs_decoder dec;
	struct fw_debounce button;
	uint32_t debug_hold_until;
	bool debug_holding;
	bool light_on;
	uint32_t light_on_since;
	bool hung; /* FS_CMD_DEBUG_HANG: the task does nothing until a reset */
} g;

void fw_isr_uart_rx(uint8_t byte)
{
	uint8_t head = rx_head;
	if ((uint8_t)(head + 1u) == rx_tail) {
		rx_dropped = (uint16_t)(rx_dropped + 1u);
		return;
	}
	rx_buf[head] = byte;
	rx_head = (uint8_t)(head + 1u);
}

void fw_isr_seq_timer(void)
{
	fw_seq_on_timer(&g.seq);
}

/* ---- output ------------------------------------------------------------------------------ */

static void send(const struct fs_frame *f)
{
	uint8_t buf[FS_PROTO_MAX_FRAME];
	size_t n = 0;
	if (fs_frame_encode(f, buf, sizeof(buf), &n) == 0)
		hal_uart_write(buf, n);
}

static void send_ack(uint8_t cmd, uint8_t seq)
{
	struct fs_frame f;
	fs_frame_init(&f, FS_RSP_ACK, seq);
	fs_ack_put(&f, cmd);
	send(&f);
}

static void send_nack(uint8_t err, uint8_t cmd, uint8_t seq)
{
	struct fs_frame f;
	struct fs_nack n = { .err = err, .cmd = cmd };
	fs_frame_init(&f, FS_RSP_NACK, seq);
	fs_nack_put(&f, &n);
	send(&f);
}

static void event_init(struct fs_frame *f, uint8_t type)
{
	fs_frame_init(f, type, g.evt_seq);
	g.evt_seq = (uint8_t)(g.evt_seq + 1u);
}

static void send_report(uint8_t result)
{
	struct fs_frame f;
	struct fs_report r;
	memset(&r, 0, sizeof(r));
	r.result = result;
	r.trigger = g.trigger;
	r.scan = (uint16_t)(g.scans + (result == FS_REPORT_DONE ? 0u : 1u));
	r.steps = g.seq.next;
	r.lines_end = (uint8_t)hal_lines_read();
	for (unsigned i = 0; i < FS_STEP__COUNT && i < r.steps; i++) {
		r.tick[i] = g.seq.tick[i];
		r.lines[i] = g.seq.lines[i];
	}
	event_init(&f, FS_EVT_REPORT);
	fs_report_put(&f, &r);
	send(&f);
}

/* Lights off first, then tell the host. A running sequence ends with a FAULT report. */
static void enter_fault(uint8_t code)
{
	bool was_busy = g.state == FS_STATE_BUSY;
	fw_seq_stop(&g.seq);
	g.state = FS_STATE_FAULT;
	g.fault = code;
	g.light_on = false;

	struct fs_frame f;
	struct fs_fault x = { .code = code, .lines = (uint8_t)hal_lines_read() };
	event_init(&f, FS_EVT_FAULT);
	fs_fault_put(&f, &x);
	send(&f);
	if (was_busy)
		send_report(FS_REPORT_FAULT);
}

static void start_sequence(uint8_t trigger)
{
	g.trigger = trigger;
	g.state = FS_STATE_BUSY;
	fw_seq_start(&g.seq, hal_ticks(), hal_tick_hz());
}

/* ---- commands ---------------------------------------------------------------------------- */

static bool body_len_is(const struct fs_frame *f, uint8_t len)
{
	if (f->len == len)
		return true;
	send_nack(FS_ERR_LENGTH, f->type, f->seq);
	return false;
}

static void handle(const struct fs_frame *f)
{
	if (!fs_type_is_command(f->type)) {
		send_nack(FS_ERR_UNKNOWN_CMD, f->type, f->seq);
		return;
	}
	if (f->version != FS_PROTO_VERSION && f->type != FS_CMD_HELLO) {
		send_nack(FS_ERR_VERSION, f->type, f->seq);
		return;
	}

	struct fs_frame r;
	switch (f->type) {
	case FS_CMD_HELLO: {
		struct fs_hello h = {
			.proto_version = FS_PROTO_VERSION,
			.fw_major = FW_VERSION_MAJOR,
			.fw_minor = FW_VERSION_MINOR,
			.board = hal_board_id(),
			.tick_hz = hal_tick_hz(),
			.max_body = FS_PROTO_MAX_BODY,
		};
		fs_frame_init(&r, FS_RSP_HELLO, f->seq);
		fs_hello_put(&r, &h);
		send(&r);
		return;
	}
	case FS_CMD_GET_TIMING:
		if (!body_len_is(f, 0))
			return;
		fs_frame_init(&r, FS_RSP_TIMING, f->seq);
		fs_timing_put(&r, &g.timing);
		send(&r);
		return;
	case FS_CMD_SET_TIMING: {
		struct fs_timing t;
		struct fw_seq plan;
		if (fs_timing_get(f, &t) < 0) {
			send_nack(FS_ERR_LENGTH, f->type, f->seq);
			return;
		}
		if (g.state == FS_STATE_BUSY) {
			send_nack(FS_ERR_BUSY, f->type, f->seq);
			return;
		}
		if (fw_seq_plan(&plan, &t, hal_tick_hz()) < 0) {
			send_nack(FS_ERR_RANGE, f->type, f->seq);
			return;
		}
		g.timing = t;
		g.seq = plan;
		send_ack(f->type, f->seq);
		return;
	}
	case FS_CMD_ARM:
	case FS_CMD_FIRE:
		if (!body_len_is(f, 0))
			return;
		if (g.state == FS_STATE_BUSY) {
			send_nack(FS_ERR_BUSY, f->type, f->seq);
			return;
		}
		if (g.state == FS_STATE_FAULT) {
			send_nack(FS_ERR_FAULT, f->type, f->seq);
			return;
		}
		send_ack(f->type, f->seq);
		if (f->type == FS_CMD_ARM)
			g.state = FS_STATE_ARMED;
		else
			start_sequence(FS_TRIGGER_HOST);
		return;
	case FS_CMD_DISARM:
	case FS_CMD_CLEAR_FAULT:
		if (!body_len_is(f, 0))
			return;
		if (g.state == FS_STATE_BUSY) {
			send_nack(FS_ERR_BUSY, f->type, f->seq);
			return;
		}
		if (f->type == FS_CMD_DISARM && g.state == FS_STATE_ARMED)
			g.state = FS_STATE_IDLE;
		if (f->type == FS_CMD_CLEAR_FAULT && g.state == FS_STATE_FAULT) {
			g.state = FS_STATE_IDLE;
			g.fault = FS_FAULT_NONE;
		}
		send_ack(f->type, f->seq);
		return;
	case FS_CMD_ABORT: {
		if (!body_len_is(f, 0))
			return;
		bool was_busy = g.state == FS_STATE_BUSY;
		fw_seq_stop(&g.seq); /* lights off whatever the state */
		if (g.state != FS_STATE_FAULT)
			g.state = FS_STATE_IDLE;
		send_ack(f->type, f->seq);
		if (was_busy)
			send_report(FS_REPORT_ABORTED);
		return;
	}
	case FS_CMD_STATUS: {
		struct fs_status s;
		if (!body_len_is(f, 0))
			return;
		fw_core_status(&s);
		fs_frame_init(&r, FS_RSP_STATUS, f->seq);
		fs_status_put(&r, &s);
		send(&r);
		return;
	}
	case FS_CMD_DEBUG_BUTTON: {
		uint16_t hold = 0;
		if (!hal_debug_inputs())
			break;
		if (fs_debug_button_get(f, &hold) < 0) {
			send_nack(FS_ERR_LENGTH, f->type, f->seq);
			return;
		}
		g.debug_holding = true;
		g.debug_hold_until = hal_ms() + hold;
		send_ack(f->type, f->seq);
		return;
	}
	case FS_CMD_DEBUG_HANG:
		if (!hal_debug_inputs())
			break;
		if (!body_len_is(f, 0))
			return;
		send_ack(f->type, f->seq);
		g.hung = true;
		return;
	default:
		break;
	}
	send_nack(FS_ERR_UNKNOWN_CMD, f->type, f->seq);
}

/* ---- the task ---------------------------------------------------------------------------- */

void fw_core_status(struct fs_status *ret)
{
	ret->state = g.state;
	ret->fault = g.fault;
	ret->reset_cause = g.reset_cause;
	ret->lines = (uint8_t)hal_lines_read();
	ret->scans = g.scans;
	ret->rx_errors = g.rx_errors;
	ret->buttons = g.buttons;
	ret->uptime_ms = hal_ms();
}

void fw_core_init(void)
{
	hal_seq_timer_cancel();
	hal_lines_write(0, FS_LINES_LIGHT | FS_LINES_SHUT);
	memset(&g, 0, sizeof(g));
	rx_tail = rx_head;
	g.rx_dropped_seen = rx_dropped;
	fs_timing_default(&g.timing);
	fs_decoder_init(&g.dec);
	fw_debounce_init(&g.button, FW_DEBOUNCE_MS, hal_ms());
	/* The defaults are within bounds at any tick rate >= 100 kHz; a board slower than that
	 * starts in FAULT with lights off rather than with an unplayable plan. */
	int plan_ok = fw_seq_plan(&g.seq, &g.timing, hal_tick_hz());
	g.reset_cause = hal_reset_cause();
	g.state = FS_STATE_IDLE;
	hal_wdt_start(FW_WDT_TIMEOUT_MS);

	struct fs_frame f;
	struct fs_boot b = { .reset_cause = g.reset_cause, .proto_version = FS_PROTO_VERSION };
	event_init(&f, FS_EVT_BOOT);
	fs_boot_put(&f, &b);
	send(&f);
	if (g.reset_cause == FS_RESET_WATCHDOG)
		enter_fault(FS_FAULT_WATCHDOG);
	else if (plan_ok < 0)
		enter_fault(FS_FAULT_HAL);
}

static void poll_rx(void)
{
	/* Bytes lost to a full ring break the frame they belonged to; the decoder rejects that
	 * frame, so only the count needs noting here. */
	uint16_t dropped = rx_dropped;
	if (dropped != g.rx_dropped_seen) {
		g.rx_dropped_seen = dropped;
		fs_decoder_init(&g.dec);
	}
	while (rx_tail != rx_head && !g.hung) {
		uint8_t tail = rx_tail;
		uint8_t byte = rx_buf[tail];
		rx_tail = (uint8_t)(tail + 1u);
		struct fs_frame f;
		int r = fs_decoder_feed(&g.dec, byte, &f);
		if (r == 1) {
			handle(&f);
		} else if (r < 0) {
			g.rx_errors = (uint16_t)(g.rx_errors + 1u);
			send_nack(fs_err_from_decode(r), 0, 0);
		}
	}
}

static void poll_sequence(void)
{
	if (g.state != FS_STATE_BUSY || !g.seq.finished)
		return;
	g.seq.finished = false;
	if (g.seq.late) {
		enter_fault(FS_FAULT_OVERRUN);
		return;
	}
	g.scans = (uint16_t)(g.scans + 1u);
	g.state = FS_STATE_IDLE;
	send_report(FS_REPORT_DONE);
}

static void poll_button(uint32_t now)
{
	if (g.debug_holding && (int32_t)(now - g.debug_hold_until) >= 0)
		g.debug_holding = false;
	bool raw = hal_button_raw() || g.debug_holding;
	if (!fw_debounce_update(&g.button, raw, now))
		return;

	g.buttons = (uint16_t)(g.buttons + 1u);
	bool start = g.state == FS_STATE_ARMED;
	struct fs_frame f;
	struct fs_button b = { .started = start ? 1u : 0u, .count = g.buttons };
	event_init(&f, FS_EVT_BUTTON);
	fs_button_put(&f, &b);
	send(&f);
	if (start)
		start_sequence(FS_TRIGGER_BUTTON);
}

/* Safety net independent of the sequence timer: no light stays on past FS_LIGHT_MAX_MS. */
static void poll_lights(uint32_t now)
{
	if (!(hal_lines_read() & FS_LINES_LIGHT)) {
		g.light_on = false;
		return;
	}
	if (!g.light_on) {
		g.light_on = true;
		g.light_on_since = now;
		return;
	}
	if (now - g.light_on_since > FS_LIGHT_MAX_MS)
		enter_fault(FS_FAULT_LIGHT_TIMEOUT);
}

void fw_core_poll(void)
{
	if (g.hung)
		return;
	uint32_t now = hal_ms();
	hal_wdt_kick();
	poll_rx();
	poll_sequence();
	poll_button(now);
	poll_lights(now);
	hal_led_write(fw_led_pattern(g.state, now));
}
