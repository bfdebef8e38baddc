#include "core/debounce.h"

void fw_debounce_init(struct fw_debounce *d, uint32_t hold_ms, uint32_t now_ms)
{
	d->stable = false;
	d->last_raw = false;
	d->since = now_ms;
	d->hold_ms = hold_ms;
}

bool fw_debounce_update(struct fw_debounce *d, bool raw, uint32_t now_ms)
{
	if (raw != d->last_raw) {
		d->last_raw = raw;
		d->since = now_ms;
		return false;
	}
	if (raw == d->stable || now_ms - d->since < d->hold_ms)
		return false;
	d->stable = raw;
	return raw;
}
