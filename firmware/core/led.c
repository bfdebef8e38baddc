#include "core/led.h"

#include "protocol/protocol.h"

bool fw_led_pattern(uint8_t state, uint32_t now_ms)
{
	switch (state) {
	case FS_STATE_ARMED:
		return true;
	case FS_STATE_BUSY:
		return (now_ms % 100u) < 50u;
	case FS_STATE_FAULT: {
		uint32_t p = now_ms % 1000u;
		return p < 100u || (p >= 200u && p < 300u);
	}
	case FS_STATE_IDLE:
	default:
		return (now_ms % 2000u) < 100u;
	}
}
