/* Status LED patterns, a pure function of state and time. */
#ifndef FACESCAN_FW_LED_H
#define FACESCAN_FW_LED_H

#include <stdbool.h>
#include <stdint.h>

/* idle: 100 ms flash every 2 s; armed: steady on; busy: 10 Hz blink;
 * fault: two 100 ms flashes per second. */
bool fw_led_pattern(uint8_t state, uint32_t now_ms);

#endif
