#include "core/sequence.h"

#include <errno.h>

#include "hal.h"

uint32_t fw_us_to_ticks(uint32_t us, uint32_t tick_hz)
{
	return (uint32_t)(((uint64_t)us * tick_hz + 500000u) / 1000000u);
}

int fw_seq_plan(struct fw_seq *s, const struct fs_timing *t, uint32_t tick_hz)
{
	if (fs_timing_validate(t) < 0 || tick_hz == 0)
		return -ERANGE;
	const uint32_t delta[FS_STEP__COUNT] = {
		0,
		fw_us_to_ticks(t->proj_settle_us, tick_hz),
		fw_us_to_ticks(t->exposure_us, tick_hz),
		fw_us_to_ticks(t->proj_hold_us, tick_hz),
		fw_us_to_ticks(t->flash_delay_us, tick_hz),
		fw_us_to_ticks(t->flash_settle_us, tick_hz),
		fw_us_to_ticks(t->flash_exposure_us, tick_hz),
		fw_us_to_ticks(t->flash_hold_us, tick_hz),
	};
	static const uint8_t set[FS_STEP__COUNT] = {
		FS_LINES_PROJ, FS_LINES_SHUT, 0, 0, FS_LINE_FLASH, FS_LINES_SHUT, 0, 0,
	};
	static const uint8_t clear[FS_STEP__COUNT] = {
		0, 0, FS_LINES_SHUT, FS_LINES_PROJ, 0, 0, FS_LINES_SHUT, FS_LINE_FLASH,
	};
	for (unsigned i = 1; i < FS_STEP__COUNT; i++)
		if (delta[i] == 0)
			return -ERANGE;

	uint32_t at = 0;
	for (unsigned i = 0; i < FS_STEP__COUNT; i++) {
		at += delta[i];
		s->step[i].at = at;
		s->step[i].set = set[i];
		s->step[i].clear = clear[i];
	}
	/* ISR latency allowance: 10 us, and at least one tick. */
	s->late_ticks = 1u + tick_hz / 100000u;
	s->running = false;
	s->finished = false;
	s->late = false;
	s->next = 0;
	return 0;
}

void fw_seq_start(struct fw_seq *s, uint32_t now, uint32_t tick_hz)
{
	uint32_t lead = tick_hz / 10000u; /* 100 us */
	if (lead < 2)
		lead = 2;
	for (unsigned i = 0; i < FS_STEP__COUNT; i++) {
		s->tick[i] = 0;
		s->lines[i] = 0;
	}
	s->next = 0;
	s->late = false;
	s->finished = false;
	s->t0 = now + lead;
	s->running = true;
	hal_seq_timer_arm(s->t0 + s->step[0].at);
}

void fw_seq_on_timer(struct fw_seq *s)
{
	if (!s->running || s->next >= FS_STEP__COUNT)
		return;
	uint8_t i = s->next;
	const struct fw_step *st = &s->step[i];

	hal_lines_write(st->set, st->clear); /* the edge: one port write */
	uint32_t rel = hal_ticks() - s->t0;
	s->tick[i] = rel;
	s->lines[i] = (uint8_t)hal_lines_read();
	s->next = (uint8_t)(i + 1);

	if ((int32_t)(rel - st->at) > (int32_t)s->late_ticks) {
		/* Too late to keep the lockstep promise: stop with everything dark. */
		hal_lines_write(0, FS_LINES_LIGHT | FS_LINES_SHUT);
		s->late = true;
	}
	if (s->late || s->next == FS_STEP__COUNT) {
		s->running = false;
		s->finished = true;
		return;
	}
	hal_seq_timer_arm(s->t0 + s->step[s->next].at);
}

void fw_seq_stop(struct fw_seq *s)
{
	hal_seq_timer_cancel();
	s->running = false;
	hal_lines_write(0, FS_LINES_LIGHT | FS_LINES_SHUT);
}
