/* Button debounce by sampling: a level counts once it has been stable FW_DEBOUNCE_MS. */
#ifndef FACESCAN_FW_DEBOUNCE_H
#define FACESCAN_FW_DEBOUNCE_H

#include <stdbool.h>
#include <stdint.h>

struct fw_debounce {
	bool stable;     /* debounced level */
	bool last_raw;   /* level at the previous sample */
	uint32_t since;  /* ms when last_raw last changed */
	uint32_t hold_ms;
};

void fw_debounce_init(struct fw_debounce *d, uint32_t hold_ms, uint32_t now_ms);
/* Feed one sample; returns true exactly once per debounced press (released -> pressed). */
bool fw_debounce_update(struct fw_debounce *d, bool raw, uint32_t now_ms);

#endif
