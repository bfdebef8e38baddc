/*
 * The one seam between the portable firmware core (firmware/core) and a board
 * (firmware/boards/<board>/). A board implements every function below with register access
 * (or a simulation, for the native board) and contains no logic; the core never touches a
 * register.
 *
 * Interrupts: a board's interrupt handlers only call the fw_isr_* entry points declared in
 * core/fw.h (UART byte received, sequence timer compare). Everything else runs in the main
 * loop, which calls fw_core_poll() forever.
 */
#ifndef FACESCAN_HAL_H
#define FACESCAN_HAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Board bring-up: clocks, pins (all FS_LINE_* outputs low first), UART, tick timer. */
void hal_init(void);

/* Free-running tick counter at hal_tick_hz(); wraps at 2^32. Safe from interrupt context. */
uint32_t hal_ticks(void);
uint32_t hal_tick_hz(void);
/* Milliseconds since reset (wraps after ~49 days). */
uint32_t hal_ms(void);

/* Drive the FS_LINE_* outputs: bits in `set` go high, bits in `clear` go low, all in ONE
 * port write (so edges on several lines happen on the same bus cycle). Safe from interrupt
 * context. A bit in both masks goes low (lights-off wins). */
void hal_lines_write(uint32_t set, uint32_t clear);
/* Current output levels (FS_LINE_* mask). */
uint32_t hal_lines_read(void);

/* Arrange for fw_isr_seq_timer() to be called from interrupt context at the first tick
 * t with (int32_t)(t - at_tick) >= 0 — late rather than never if at_tick has passed. Only
 * one compare is pending at a time; arming again replaces it. */
void hal_seq_timer_arm(uint32_t at_tick);
/* Cancel a pending compare. After return fw_isr_seq_timer() is not called until re-armed. */
void hal_seq_timer_cancel(void);

/* Raw level of the booth button: true while pressed (the core debounces). */
bool hal_button_raw(void);
/* Status LED. */
void hal_led_write(bool on);

/* Queue bytes for transmission to the host; may block until they fit. */
void hal_uart_write(const uint8_t *buf, size_t len);

/* Watchdog: start with a timeout, then kick it from the main loop. Once started it cannot be
 * stopped; expiry resets the MCU and hal_reset_cause() reports FS_RESET_WATCHDOG. */
void hal_wdt_start(uint32_t timeout_ms);
void hal_wdt_kick(void);

/* Why the MCU last reset (enum fs_reset_cause). */
uint8_t hal_reset_cause(void);
/* enum fs_board */
uint8_t hal_board_id(void);
/* true on boards where FS_CMD_DEBUG_BUTTON may stand in for the button (emulators only). */
bool hal_debug_inputs(void);
/* Sleep until the next interrupt (WFI), or return at once. */
void hal_idle(void);

#ifdef __cplusplus
}
#endif

#endif
