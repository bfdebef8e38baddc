/*
 * QEMU lm3s6965evb board (TI Stellaris LM3S6965, Cortex-M3): register-level HAL, vector
 * table, reset handler. Lines on GPIO port B (PB0..PB7 = FS_LINE_* bits 0..7), status LED
 * on PF0, host link on UART0 (PL011), tick from SysTick at 100 kHz, watchdog WDT0.
 *
 * The sequence timer is the SysTick interrupt itself: each 10 us tick it compares the tick
 * count with the armed step and does the step's port write. So in QEMU the emulator's own
 * `systick_timer_tick` trace is the firmware's clock, and the `pl061_set_output` trace of
 * port B shows each step's edges between two ticks.
 *
 * Watchdog: WDT0 interrupts at the first time-out (the loop has not kicked for half the
 * timeout): that interrupt drives every line low at once and leaves a note in .noinit RAM,
 * and the second time-out resets. The note gives the reset cause where RESC does not (QEMU
 * does not set RESC.WDT).
 *
 * The booth button is not wired here: a headless emulator cannot press a GPIO input, so
 * this board accepts FS_CMD_DEBUG_BUTTON instead (hal_debug_inputs() is true).
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "boards/cortex_m.h"
#include "core/fw.h"
#include "hal.h"
#include "protocol/protocol.h"

/* QEMU derives the system clock from RCC.SYSDIV of a 200 MHz PLL: the reset value gives
 * 200 MHz / 16 = 12.5 MHz. */
#define SYSCLK_HZ 12500000u
#define TICK_HZ 100000u

#define SYSCTL_RESC 0x400fe05cu
#define SYSCTL_RCGC0 0x400fe100u
#define SYSCTL_RCGC1 0x400fe104u
#define SYSCTL_RCGC2 0x400fe108u

#define GPIOB 0x40005000u
#define GPIOF 0x40025000u
#define GPIO_DIR 0x400u
#define GPIO_DEN 0x51cu
/* Masked data access: address bits [9:2] select which pins a write may change. */
#define GPIO_DATA(base, mask) ((base) + ((uint32_t)(mask) << 2))

#define UART0 0x4000c000u
#define UART_DR 0x000u
#define UART_FR 0x018u
#define UART_IBRD 0x024u
#define UART_FBRD 0x028u
#define UART_LCRH 0x02cu
#define UART_CR 0x030u
#define UART_IMSC 0x038u
#define UART_ICR 0x044u
#define UART_FR_RXFE (1u << 4)
#define UART_FR_TXFF (1u << 5)
#define UART_INT_RX (1u << 4)
#define UART_INT_RT (1u << 6)
#define UART0_IRQ 5u

#define WDT0 0x40000000u
#define WDT_LOAD 0x000u
#define WDT_CTL 0x008u
#define WDT_ICR 0x00cu
#define WDT0_IRQ 18u
#define NVIC_ICER0 0xe000e180u
#define WDT_NOTE_MAGIC 0x57d6b17eu

static volatile uint32_t ticks;
static volatile uint32_t ms;
static volatile uint32_t sub_ms;
static volatile bool cmp_armed;
static volatile uint32_t cmp_at;
static uint8_t reset_cause;
__attribute__((section(".noinit"))) static volatile uint32_t wdt_note;

void hal_init(void)
{
	uint32_t resc = REG32(SYSCTL_RESC);
	REG32(SYSCTL_RESC) = 0;
	bool wdt_noted = wdt_note == WDT_NOTE_MAGIC;
	wdt_note = 0;
	if ((resc & (1u << 3)) || wdt_noted)
		reset_cause = FS_RESET_WATCHDOG;
	else if (resc & (1u << 4))
		reset_cause = FS_RESET_SOFTWARE;
	else if (resc & (1u << 0))
		reset_cause = FS_RESET_PIN;
	else
		reset_cause = FS_RESET_POWER;

	REG32(SYSCTL_RCGC0) |= 1u << 3;              /* WDT0 */
	REG32(SYSCTL_RCGC1) |= 1u << 0;              /* UART0 */
	REG32(SYSCTL_RCGC2) |= (1u << 1) | (1u << 5); /* GPIOB, GPIOF */

	/* Lines low before they become outputs. */
	REG32(GPIO_DATA(GPIOB, 0xff)) = 0;
	REG32(GPIOB + GPIO_DEN) = 0xff;
	REG32(GPIOB + GPIO_DIR) = 0xff;
	REG32(GPIO_DATA(GPIOF, 0x01)) = 0;
	REG32(GPIOF + GPIO_DEN) |= 0x01;
	REG32(GPIOF + GPIO_DIR) |= 0x01;

	/* 115200 8N1 at 12.5 MHz: 12.5e6 / (16 * 115200) = 6.78 -> 6 + 50/64. */
	REG32(UART0 + UART_CR) = 0;
	REG32(UART0 + UART_IBRD) = 6;
	REG32(UART0 + UART_FBRD) = 50;
	REG32(UART0 + UART_LCRH) = (3u << 5) | (1u << 4); /* 8 bits, FIFOs on */
	REG32(UART0 + UART_IMSC) = UART_INT_RX | UART_INT_RT;
	REG32(UART0 + UART_CR) = (1u << 0) | (1u << 8) | (1u << 9);
	cm_nvic_enable(UART0_IRQ);

	REG32(SYST_RVR) = SYSCLK_HZ / TICK_HZ - 1u;
	REG32(SYST_CVR) = 0;
	REG32(SYST_CSR) = SYST_CSR_ENABLE | SYST_CSR_TICKINT | SYST_CSR_CLKSOURCE;
}

uint32_t hal_ticks(void)
{
	return ticks;
}

uint32_t hal_tick_hz(void)
{
	return TICK_HZ;
}

uint32_t hal_ms(void)
{
	return ms;
}

void hal_lines_write(uint32_t set, uint32_t clear)
{
	/* One store: the mask in the address selects every pin that changes, the data their
	 * new levels. */
	REG32(GPIO_DATA(GPIOB, (set | clear) & 0xffu)) = set & ~clear;
}

uint32_t hal_lines_read(void)
{
	return REG32(GPIO_DATA(GPIOB, 0xff)) & 0xffu;
}

void hal_seq_timer_arm(uint32_t at_tick)
{
	cmp_armed = false;
	cmp_at = at_tick;
	cmp_armed = true;
}

void hal_seq_timer_cancel(void)
{
	cmp_armed = false;
}

bool hal_button_raw(void)
{
	return false;
}

void hal_led_write(bool on)
{
	REG32(GPIO_DATA(GPIOF, 0x01)) = on ? 1u : 0u;
}

void hal_uart_write(const uint8_t *buf, size_t len)
{
	for (size_t i = 0; i < len; i++) {
		while (REG32(UART0 + UART_FR) & UART_FR_TXFF)
			;
		REG32(UART0 + UART_DR) = buf[i];
	}
}

void hal_wdt_start(uint32_t timeout_ms)
{
	/* The WDT interrupts at the first time-out and resets at the second: load half. */
	REG32(WDT0 + WDT_LOAD) = timeout_ms / 2u * (SYSCLK_HZ / 1000u);
	REG32(WDT0 + WDT_CTL) = (1u << 0) | (1u << 1); /* INTEN (starts it), RESEN */
	cm_nvic_enable(WDT0_IRQ);
}

void hal_wdt_kick(void)
{
	REG32(WDT0 + WDT_ICR) = 1; /* clears the interrupt and reloads */
}

uint8_t hal_reset_cause(void)
{
	return reset_cause;
}

uint8_t hal_board_id(void)
{
	return FS_BOARD_LM3S6965EVB;
}

bool hal_debug_inputs(void)
{
	return true;
}

/* No WFI here: under QEMU's -icount sleep=off a SysTick that fires while the CPU sleeps is
 * only taken at the following tick, so the firmware would count half the ticks. Spinning
 * keeps the count exact (the emulated CPU has no power to save). */
void hal_idle(void)
{
}

/* ---- interrupts -------------------------------------------------------------------------- */

static void systick_isr(void)
{
	uint32_t t = ticks + 1u;
	ticks = t;
	if (++sub_ms == TICK_HZ / 1000u) {
		sub_ms = 0;
		ms = ms + 1u;
	}
	if (cmp_armed && (int32_t)(t - cmp_at) >= 0) {
		cmp_armed = false;
		fw_isr_seq_timer();
	}
}

/* First watchdog time-out: the main loop is stuck. Dark now, note why, let it reset. */
static void wdt0_isr(void)
{
	hal_lines_write(0, FS_LINES_LIGHT | FS_LINES_SHUT);
	wdt_note = WDT_NOTE_MAGIC;
	REG32(NVIC_ICER0) = 1u << WDT0_IRQ; /* the interrupt stays asserted until the reset */
}

static void uart0_isr(void)
{
	/* Acknowledge first, then drain: a byte arriving meanwhile raises it again. */
	REG32(UART0 + UART_ICR) = UART_INT_RX | UART_INT_RT;
	while (!(REG32(UART0 + UART_FR) & UART_FR_RXFE))
		fw_isr_uart_rx((uint8_t)REG32(UART0 + UART_DR));
}

/* Any fault: lights and shutters off, then wait for the watchdog. */
static void fault_isr(void)
{
	hal_lines_write(0, FS_LINES_LIGHT | FS_LINES_SHUT);
	for (;;)
		;
}

int main(void);

void reset_handler(void)
{
	cm_crt_init();
	main();
	fault_isr();
}

extern uint32_t _estack;

__attribute__((section(".vectors"), used)) static const cm_vector vectors[16 + 48] = {
	[0] = (cm_vector)(uintptr_t)&_estack,
	[1] = reset_handler,
	[2] = fault_isr,  /* NMI */
	[3] = fault_isr,  /* HardFault */
	[4] = fault_isr,  /* MemManage */
	[5] = fault_isr,  /* BusFault */
	[6] = fault_isr,  /* UsageFault */
	[11] = fault_isr, /* SVCall */
	[14] = fault_isr, /* PendSV */
	[15] = systick_isr,
	[16 + UART0_IRQ] = uart0_isr,
	[16 + WDT0_IRQ] = wdt0_isr,
};

int main(void)
{
	hal_init();
	fw_core_init();
	cm_irq_enable();
	for (;;) {
		fw_core_poll();
		hal_idle();
	}
}
