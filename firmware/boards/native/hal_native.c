/* The HAL on the host: virtual clock, simulated port, compare timer, UART and watchdog. */
#include "boards/native/native.h"

#include <string.h>

#include "core/fw.h"
#include "hal.h"
#include "protocol/protocol.h"

static struct {
	uint64_t now;
	uint8_t lines;
	bool led;
	bool button;
	bool debug_inputs;
	uint8_t reset_cause;
	bool cmp_armed;
	uint32_t cmp_at;
	uint32_t latency;
	bool wdt_on;
	bool wdt_expired;
	uint64_t wdt_deadline;
	uint32_t wdt_timeout_ticks;
	struct native_edge edges[NATIVE_EDGE_LOG];
	size_t n_edges;
	uint8_t tx[16384];
	size_t n_tx;
	native_uart_sink sink;
	void *sink_ctx;
} b;

void native_reset(uint8_t cause)
{
	uint64_t now = b.now;
	native_uart_sink sink = b.sink;
	void *ctx = b.sink_ctx;
	bool debug = b.debug_inputs;
	memset(&b, 0, sizeof(b));
	b.now = now;
	b.sink = sink;
	b.sink_ctx = ctx;
	b.debug_inputs = debug;
	b.reset_cause = cause;
}

static uint64_t due_tick(void)
{
	/* The compare fires at the first tick at or after cmp_at (late rather than never). */
	int32_t d = (int32_t)(b.cmp_at - (uint32_t)b.now);
	return b.now + (d > 0 ? (uint64_t)d : 0u) + b.latency;
}

uint64_t native_next_due(void)
{
	return b.cmp_armed ? due_tick() - b.now : UINT64_MAX;
}

void native_advance(uint64_t ticks)
{
	uint64_t end = b.now + ticks;
	while (b.cmp_armed && due_tick() <= end) {
		b.now = due_tick();
		b.cmp_armed = false;
		fw_isr_seq_timer();
	}
	b.now = end;
	if (b.wdt_on && b.now > b.wdt_deadline)
		b.wdt_expired = true;
}

uint64_t native_now(void)
{
	return b.now;
}

void native_uart_inject(const uint8_t *buf, size_t len)
{
	for (size_t i = 0; i < len; i++)
		fw_isr_uart_rx(buf[i]);
}

size_t native_uart_take(uint8_t *buf, size_t cap)
{
	size_t n = b.n_tx < cap ? b.n_tx : cap;
	memcpy(buf, b.tx, n);
	memmove(b.tx, b.tx + n, b.n_tx - n);
	b.n_tx -= n;
	return n;
}

void native_set_uart_sink(native_uart_sink fn, void *ctx)
{
	b.sink = fn;
	b.sink_ctx = ctx;
}

void native_set_button(bool pressed)
{
	b.button = pressed;
}

bool native_led(void)
{
	return b.led;
}

void native_set_debug_inputs(bool on)
{
	b.debug_inputs = on;
}

size_t native_edges(const struct native_edge **ret)
{
	*ret = b.edges;
	return b.n_edges;
}

void native_clear_edges(void)
{
	b.n_edges = 0;
}

bool native_wdt_expired(void)
{
	return b.wdt_expired;
}

void native_set_isr_latency(uint32_t ticks)
{
	b.latency = ticks;
}

/* ---- hal.h ------------------------------------------------------------------------------- */

void hal_init(void)
{
	b.lines = 0;
}

uint32_t hal_ticks(void)
{
	return (uint32_t)b.now;
}

uint32_t hal_tick_hz(void)
{
	return NATIVE_TICK_HZ;
}

uint32_t hal_ms(void)
{
	return (uint32_t)(b.now / (NATIVE_TICK_HZ / 1000u));
}

void hal_lines_write(uint32_t set, uint32_t clear)
{
	uint8_t before = b.lines;
	b.lines = (uint8_t)((b.lines | set) & ~clear);
	if (b.lines != before && b.n_edges < NATIVE_EDGE_LOG)
		b.edges[b.n_edges++] = (struct native_edge){ b.now, before, b.lines };
}

uint32_t hal_lines_read(void)
{
	return b.lines;
}

void hal_seq_timer_arm(uint32_t at_tick)
{
	b.cmp_at = at_tick;
	b.cmp_armed = true;
}

void hal_seq_timer_cancel(void)
{
	b.cmp_armed = false;
}

bool hal_button_raw(void)
{
	return b.button;
}

void hal_led_write(bool on)
{
	b.led = on;
}

void hal_uart_write(const uint8_t *buf, size_t len)
{
	if (b.sink) {
		b.sink(buf, len, b.sink_ctx);
		return;
	}
	size_t room = sizeof(b.tx) - b.n_tx;
	if (len > room)
		len = room;
	memcpy(b.tx + b.n_tx, buf, len);
	b.n_tx += len;
}

void hal_wdt_start(uint32_t timeout_ms)
{
	b.wdt_on = true;
	b.wdt_timeout_ticks = timeout_ms * (NATIVE_TICK_HZ / 1000u);
	b.wdt_deadline = b.now + b.wdt_timeout_ticks;
}

void hal_wdt_kick(void)
{
	if (b.wdt_on && !b.wdt_expired)
		b.wdt_deadline = b.now + b.wdt_timeout_ticks;
}

uint8_t hal_reset_cause(void)
{
	return b.reset_cause;
}

uint8_t hal_board_id(void)
{
	return FS_BOARD_NATIVE;
}

bool hal_debug_inputs(void)
{
	return b.debug_inputs;
}

void hal_idle(void)
{
}
