/* Helpers of the serial driver tests (test_serial, test_serial_firmware): one copy. */
#ifndef FACESCAN_TESTS_SERIAL_HELPERS_H
#define FACESCAN_TESTS_SERIAL_HELPERS_H

#include <errno.h>
#include <stdint.h>

#include "facescan/serial.h"

/* The next event of `type`, skipping up to nine others (the boot greeting, a button): 0,
 * -ENOMSG when it did not come among them, or what fscan_serial_next_event() returned. */
static int next_event_of(struct fscan_serial *link, uint8_t type, struct fs_frame *ret, int timeout_ms)
{
	for (int i = 0; i < 10; i++) {
		int r = fscan_serial_next_event(link, ret, timeout_ms);
		if (r < 0)
			return r;
		if (ret->type == type)
			return 0;
	}
	return -ENOMSG;
}

#endif
