/*
 * The portable trigger-controller core. No register access: everything goes through hal.h.
 *
 * A board's reset handler calls hal_init(), fw_core_init(), then fw_core_poll() forever.
 * Its interrupt handlers only call the two fw_isr_* entry points below; the main-loop task
 * (fw_core_poll) does all the work: frames, commands, reports, debounce, LED, watchdog,
 * light-safety checks. The one exception is the sequence step itself (one precomputed port
 * write per timer compare), which must happen in the timer interrupt to keep its timing.
 */
#ifndef FACESCAN_FW_H
#define FACESCAN_FW_H

#include <stdbool.h>
#include <stdint.h>

#include "protocol/protocol.h"

#ifdef __cplusplus
extern "C" {
#endif

#define FW_VERSION_MAJOR 1u
#define FW_VERSION_MINOR 0u

#define FW_WDT_TIMEOUT_MS 500u /* watchdog timeout; the main loop kicks it every pass */
#define FW_DEBOUNCE_MS 20u     /* the button must be stable this long to count */
#define FW_RX_RING 256u        /* bytes buffered between the UART interrupt and the loop */

/* Reset the core's state (lights off, IDLE, or FAULT after a watchdog reset), start the
 * watchdog and send EVT_BOOT (+ EVT_FAULT after a watchdog reset). */
void fw_core_init(void);
/* One pass of the main-loop task. Never blocks except in hal_uart_write. */
void fw_core_poll(void);

/* Interrupt entry points. */
void fw_isr_uart_rx(uint8_t byte);
void fw_isr_seq_timer(void);

/* Read-only view of the state for the native board's tests and the STATUS reply. */
void fw_core_status(struct fs_status *ret);

#ifdef __cplusplus
}
#endif

#endif
