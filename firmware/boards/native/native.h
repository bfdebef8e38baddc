/*
 * The native board: the HAL simulated on the host with a virtual 1 MHz clock. Used by the
 * unit tests (which drive time and inputs through the back doors below, like an emulated
 * GPIO) and by facescan-fw-native, which runs the firmware behind a pseudo-terminal.
 * Not thread-safe: one driver calls everything from one thread.
 */
#ifndef FACESCAN_BOARD_NATIVE_H
#define FACESCAN_BOARD_NATIVE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define NATIVE_TICK_HZ 1000000u
#define NATIVE_EDGE_LOG 256u

/* A write to the lines that changed something. */
struct native_edge {
	uint64_t tick;
	uint8_t before;
	uint8_t after;
};

/* Power-on the simulated board: lines low, timer idle, watchdog stopped, logs cleared, the
 * clock keeps running. hal_reset_cause() will report `cause` (enum fs_reset_cause). */
void native_reset(uint8_t cause);
/* Advance virtual time, calling fw_isr_seq_timer() at each due compare (plus the injected
 * latency), and noting watchdog expiry. */
void native_advance(uint64_t ticks);
uint64_t native_now(void);
/* Ticks until the pending compare is due, or UINT64_MAX if none. */
uint64_t native_next_due(void);

/* Bytes from the host: each goes through fw_isr_uart_rx() as the UART interrupt would. */
void native_uart_inject(const uint8_t *buf, size_t len);
/* Bytes the firmware sent: drained from an internal buffer unless a sink is set. */
size_t native_uart_take(uint8_t *buf, size_t cap);
typedef void (*native_uart_sink)(const uint8_t *buf, size_t len, void *ctx);
void native_set_uart_sink(native_uart_sink fn, void *ctx);

void native_set_button(bool pressed);
bool native_led(void);
/* Whether a UART debug command may press the button (default false, as on real parts). */
void native_set_debug_inputs(bool on);

/* Line-change log since the last native_reset / native_clear_edges. */
size_t native_edges(const struct native_edge **ret);
void native_clear_edges(void);

/* Watchdog: true once the timeout has passed without a kick (the MCU would reset now). */
bool native_wdt_expired(void);
/* Fault injection: deliver every compare interrupt this many ticks late. */
void native_set_isr_latency(uint32_t ticks);

#endif
