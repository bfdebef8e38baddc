/* The scan sequence: a plan of 8 port writes computed from the timing, played back by the
 * sequence-timer interrupt, one write per compare. */
#ifndef FACESCAN_FW_SEQUENCE_H
#define FACESCAN_FW_SEQUENCE_H

#include <stdbool.h>
#include <stdint.h>

#include "protocol/protocol.h"

struct fw_step {
	uint32_t at;   /* ticks after the sequence's t0 */
	uint8_t set;   /* FS_LINE_* driven high by this step */
	uint8_t clear; /* FS_LINE_* driven low by this step */
};

struct fw_seq {
	struct fw_step step[FS_STEP__COUNT];
	uint32_t late_ticks; /* a step later than this fails the sequence (FS_FAULT_OVERRUN) */
	uint32_t t0;         /* absolute tick of step 0 */
	/* Written by the timer interrupt while running; read by the main loop once finished. */
	volatile uint8_t next;
	volatile bool running;
	volatile bool finished;
	volatile bool late;
	volatile uint32_t tick[FS_STEP__COUNT]; /* measured tick of each write, relative to t0 */
	volatile uint8_t lines[FS_STEP__COUNT]; /* output levels right after each write */
};

/* Microseconds to ticks, rounded to nearest. */
uint32_t fw_us_to_ticks(uint32_t us, uint32_t tick_hz);

/* Compute the plan. Returns -ERANGE if the timing is out of bounds or a delay would round
 * to 0 ticks at tick_hz (two steps on one tick would lose their order); s untouched then. */
int fw_seq_plan(struct fw_seq *s, const struct fs_timing *t, uint32_t tick_hz);
/* Start playing the plan: t0 is a short lead after now (so the first compare is not late). */
void fw_seq_start(struct fw_seq *s, uint32_t now, uint32_t tick_hz);
/* The timer-interrupt body: one port write, its timestamp, the next compare. */
void fw_seq_on_timer(struct fw_seq *s);
/* Stop at once (abort/fault): cancel the compare, then force lights and shutters low. */
void fw_seq_stop(struct fw_seq *s);

#endif
