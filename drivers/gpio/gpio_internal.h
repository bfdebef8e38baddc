/* Private to drivers/gpio: the handle behind struct fscan_gpio. */
#ifndef FACESCAN_GPIO_INTERNAL_H
#define FACESCAN_GPIO_INTERNAL_H

#include "facescan/gpio.h"

struct fscan_gpio {
	const struct fscan_gpio_ops *ops;
	void *ctx;
	uint64_t debounce_ns;
	bool reported;       /* debounced state the caller last heard */
	bool raw;            /* level after the last raw edge */
	uint64_t raw_since;  /* timestamp of the edge that brought `raw` */
	bool has_pending_edge;
	struct fscan_gpio_edge pending_edge;
};

#endif
