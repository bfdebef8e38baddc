/* Private to drivers/serial: the handle behind struct fscan_serial. */
#ifndef FACESCAN_SERIAL_INTERNAL_H
#define FACESCAN_SERIAL_INTERNAL_H

#include "facescan/serial.h"

#define FSCAN_SERIAL_EVENT_QUEUE 32u
#define FSCAN_SERIAL_RXBUF 512u

struct fscan_serial {
	const struct fscan_serial_ops *ops;
	void *ctx;                /* NULL while the link is down */
	char *device;
	struct fscan_serial_config cfg; /* cfg.device points at device */
	struct fs_decoder dec;
	uint8_t rx[FSCAN_SERIAL_RXBUF];
	size_t rx_pos, rx_len;    /* bytes read but not yet fed to the decoder */
	struct fs_frame events[FSCAN_SERIAL_EVENT_QUEUE];
	unsigned ev_head, ev_len;
	uint8_t seq;
	uint8_t last_nack;
	struct fscan_serial_stats stats;
};

#endif
