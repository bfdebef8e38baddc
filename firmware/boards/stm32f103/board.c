/*
 * STM32F103C8 "blue pill" board: register-level HAL, vector table, reset handler.
 *
 *   PA0..PA7   FS_LINE_* bits 0..7 (projectors 1-3, flash, shutters 1-4), push-pull; all
 *              edges of a step are one write of GPIOA_BSRR (set and reset halves together)
 *   PA9/PA10   USART1 TX/RX to the host, 115200 8N1
 *   PB0        booth button to ground, internal pull-up (pressed = low)
 *   PC13       status LED (on-board, active low)
 *   TIM2       1 MHz tick: 16-bit counter extended to 32 bits by its update interrupt;
 *              compare channel 1 calls the sequence step
 *   SysTick    1 kHz millisecond count
 *   IWDG       independent watchdog (LSI ~40 kHz)
 *
 * Clock: 8 MHz HSE crystal x9 = 72 MHz; if the crystal does not start, HSI 8 MHz.
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "boards/cortex_m.h"
#include "core/fw.h"
#include "hal.h"
#include "protocol/protocol.h"

#define TICK_HZ 1000000u

#define RCC 0x40021000u
#define RCC_CR (RCC + 0x00u)
#define RCC_CFGR (RCC + 0x04u)
#define RCC_APB2ENR (RCC + 0x18u)
#define RCC_APB1ENR (RCC + 0x1cu)
#define RCC_CSR (RCC + 0x24u)
#define FLASH_ACR 0x40022000u

#define GPIOA 0x40010800u
#define GPIOB 0x40010c00u
#define GPIOC 0x40011000u
#define GPIO_CRL 0x00u
#define GPIO_CRH 0x04u
#define GPIO_IDR 0x08u
#define GPIO_ODR 0x0cu
#define GPIO_BSRR 0x10u

#define USART1 0x40013800u
#define USART_SR 0x00u
#define USART_DR 0x04u
#define USART_BRR 0x08u
#define USART_CR1 0x0cu
#define USART_SR_RXNE (1u << 5)
#define USART_SR_TXE (1u << 7)
#define USART1_IRQ 37u

#define TIM2 0x40000000u
#define TIM_CR1 0x00u
#define TIM_DIER 0x0cu
#define TIM_SR 0x10u
#define TIM_EGR 0x14u
#define TIM_CNT 0x24u
#define TIM_PSC 0x28u
#define TIM_ARR 0x2cu
#define TIM_CCR1 0x34u
#define TIM_UIF (1u << 0)
#define TIM_CC1IF (1u << 1) /* SR */
#define TIM_CC1IE (1u << 1) /* DIER */
#define TIM_CC1G (1u << 1)  /* EGR */
#define TIM2_IRQ 28u

#define IWDG_KR 0x40003000u
#define IWDG_PR 0x40003004u
#define IWDG_RLR 0x40003008u

static uint32_t sysclk_hz = 8000000u;
static uint32_t tim_hz = 8000000u;
static volatile uint16_t tick_hi;
static volatile uint32_t ms;
static volatile bool cmp_armed; /* a step is due at cmp_at */
static volatile bool cc_on;     /* ... and channel 1 is programmed for it */
static volatile uint32_t cmp_at;
static uint8_t reset_cause;

static uint32_t irq_save(void)
{
	uint32_t primask;
	__asm__ volatile("mrs %0, primask\n cpsid i" : "=r"(primask)::"memory");
	return primask;
}

static void irq_restore(uint32_t primask)
{
	__asm__ volatile("msr primask, %0" ::"r"(primask) : "memory");
}

static void clock_init(void)
{
	REG32(RCC_CR) |= 1u << 16; /* HSEON */
	for (uint32_t i = 0; i < 200000u; i++) {
		if (REG32(RCC_CR) & (1u << 17)) {
			REG32(FLASH_ACR) = 0x12u;                 /* prefetch, 2 wait states */
			REG32(RCC_CFGR) = (7u << 18) | (1u << 16) /* PLL = HSE x 9 */
					  | (4u << 8);             /* APB1 = HCLK / 2 */
			REG32(RCC_CR) |= 1u << 24;                /* PLLON */
			while (!(REG32(RCC_CR) & (1u << 25)))
				;
			REG32(RCC_CFGR) |= 2u; /* SYSCLK = PLL */
			while ((REG32(RCC_CFGR) & (3u << 2)) != (2u << 2))
				;
			sysclk_hz = 72000000u;
			tim_hz = 72000000u; /* APB1 prescaled: timers run at 2 x PCLK1 */
			return;
		}
	}
}

void hal_init(void)
{
	uint32_t csr = REG32(RCC_CSR);
	REG32(RCC_CSR) |= 1u << 24; /* RMVF: clear the flags for next time */
	if (csr & ((1u << 29) | (1u << 30)))
		reset_cause = FS_RESET_WATCHDOG;
	else if (csr & (1u << 28))
		reset_cause = FS_RESET_SOFTWARE;
	else if (csr & ((1u << 27) | (1u << 31)))
		reset_cause = FS_RESET_POWER;
	else if (csr & (1u << 26))
		reset_cause = FS_RESET_PIN;
	else
		reset_cause = FS_RESET_OTHER;

	/* Lines low before anything else, including the clock switch. */
	REG32(RCC_APB2ENR) |= (1u << 0) | (1u << 2) | (1u << 3) | (1u << 4) | (1u << 14);
	REG32(GPIOA + GPIO_BSRR) = 0xffu << 16;
	REG32(GPIOA + GPIO_CRL) = 0x22222222u; /* PA0..7 push-pull outputs, 2 MHz */
	clock_init();

	REG32(GPIOA + GPIO_CRH) = (REG32(GPIOA + GPIO_CRH) & ~0xff0u) | 0xb0u | 0x400u;
	REG32(GPIOB + GPIO_CRL) = (REG32(GPIOB + GPIO_CRL) & ~0xfu) | 0x8u; /* PB0 pull input */
	REG32(GPIOB + GPIO_BSRR) = 1u << 0;                                  /* ... pull-up */
	REG32(GPIOC + GPIO_BSRR) = 1u << 13;                                 /* LED off */
	REG32(GPIOC + GPIO_CRH) = (REG32(GPIOC + GPIO_CRH) & ~(0xfu << 20)) | (0x2u << 20);

	REG32(USART1 + USART_BRR) = (sysclk_hz + 57600u) / 115200u;
	REG32(USART1 + USART_CR1) = (1u << 13) | (1u << 5) | (1u << 3) | (1u << 2);
	cm_nvic_enable(USART1_IRQ);

	REG32(RCC_APB1ENR) |= 1u << 0; /* TIM2 */
	REG32(TIM2 + TIM_PSC) = tim_hz / TICK_HZ - 1u;
	REG32(TIM2 + TIM_ARR) = 0xffffu;
	REG32(TIM2 + TIM_EGR) = 1u; /* load the prescaler */
	REG32(TIM2 + TIM_SR) = 0;
	REG32(TIM2 + TIM_DIER) = 1u; /* UIE: extend the counter */
	REG32(TIM2 + TIM_CR1) = 1u;
	cm_nvic_enable(TIM2_IRQ);

	REG32(SYST_RVR) = sysclk_hz / 1000u - 1u;
	REG32(SYST_CVR) = 0;
	REG32(SYST_CSR) = SYST_CSR_ENABLE | SYST_CSR_TICKINT | SYST_CSR_CLKSOURCE;
}

uint32_t hal_ticks(void)
{
	for (;;) {
		uint16_t hi = tick_hi;
		uint16_t lo = (uint16_t)REG32(TIM2 + TIM_CNT);
		uint32_t sr = REG32(TIM2 + TIM_SR);
		if (hi != tick_hi)
			continue; /* the update interrupt ran in between */
		/* Wrapped but the update interrupt has not run yet (we are in an interrupt or
		 * have them masked): count the wrap here. */
		if ((sr & TIM_UIF) && lo < 0x8000u)
			hi++;
		return ((uint32_t)hi << 16) | lo;
	}
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
	/* BSRR: low half sets, high half resets; reset wins where both are given. */
	uint32_t s = set & ~clear & 0xffu;
	REG32(GPIOA + GPIO_BSRR) = s | ((clear & 0xffu) << 16);
}

uint32_t hal_lines_read(void)
{
	return REG32(GPIOA + GPIO_ODR) & 0xffu;
}

/* Channel 1 matches the first time CNT equals at's low half; called only when `at` is less
 * than one counter period away, so that first match is `at` itself. */
static void program_compare(uint32_t at)
{
	REG32(TIM2 + TIM_SR) = ~TIM_CC1IF;
	REG32(TIM2 + TIM_CCR1) = at & 0xffffu;
	REG32(TIM2 + TIM_DIER) |= TIM_CC1IE;
	cc_on = true;
	/* Already due (late rather than never): raise the compare event by software. */
	if ((int32_t)(at - hal_ticks()) <= 0 && !(REG32(TIM2 + TIM_SR) & TIM_CC1IF))
		REG32(TIM2 + TIM_EGR) = TIM_CC1G;
}

void hal_seq_timer_arm(uint32_t at_tick)
{
	uint32_t pm = irq_save();
	cmp_at = at_tick;
	cmp_armed = true;
	cc_on = false;
	REG32(TIM2 + TIM_DIER) &= ~TIM_CC1IE;
	if ((int32_t)(at_tick - hal_ticks()) < 0x10000)
		program_compare(at_tick);
	irq_restore(pm);
}

void hal_seq_timer_cancel(void)
{
	uint32_t pm = irq_save();
	REG32(TIM2 + TIM_DIER) &= ~TIM_CC1IE;
	REG32(TIM2 + TIM_SR) = ~TIM_CC1IF;
	cmp_armed = false;
	cc_on = false;
	irq_restore(pm);
}

bool hal_button_raw(void)
{
	return !(REG32(GPIOB + GPIO_IDR) & 1u);
}

void hal_led_write(bool on)
{
	REG32(GPIOC + GPIO_BSRR) = on ? (1u << (13 + 16)) : (1u << 13);
}

void hal_uart_write(const uint8_t *buf, size_t len)
{
	for (size_t i = 0; i < len; i++) {
		while (!(REG32(USART1 + USART_SR) & USART_SR_TXE))
			;
		REG32(USART1 + USART_DR) = buf[i];
	}
}

void hal_wdt_start(uint32_t timeout_ms)
{
	REG32(IWDG_KR) = 0x5555u;             /* unlock PR/RLR */
	REG32(IWDG_PR) = 4u;                  /* LSI / 64: 625 Hz */
	REG32(IWDG_RLR) = timeout_ms * 625u / 1000u;
	REG32(IWDG_KR) = 0xaaaau;
	REG32(IWDG_KR) = 0xccccu;             /* start */
}

void hal_wdt_kick(void)
{
	REG32(IWDG_KR) = 0xaaaau;
}

uint8_t hal_reset_cause(void)
{
	return reset_cause;
}

uint8_t hal_board_id(void)
{
	return FS_BOARD_STM32F103;
}

bool hal_debug_inputs(void)
{
	return false;
}

void hal_idle(void)
{
	cm_wfi();
}

/* ---- interrupts -------------------------------------------------------------------------- */

static void systick_isr(void)
{
	ms = ms + 1u;
}

static void tim2_isr(void)
{
	if (REG32(TIM2 + TIM_SR) & TIM_UIF) {
		REG32(TIM2 + TIM_SR) = ~TIM_UIF;
		tick_hi = (uint16_t)(tick_hi + 1u);
		if (cmp_armed && !cc_on && (int32_t)(cmp_at - hal_ticks()) < 0x10000)
			program_compare(cmp_at);
	}
	if (cc_on && (REG32(TIM2 + TIM_SR) & TIM_CC1IF)) {
		REG32(TIM2 + TIM_SR) = ~TIM_CC1IF;
		REG32(TIM2 + TIM_DIER) &= ~TIM_CC1IE;
		cc_on = false;
		cmp_armed = false;
		fw_isr_seq_timer(); /* may arm the next step */
	}
}

static void usart1_isr(void)
{
	/* Reading SR then DR clears RXNE (and an overrun, whose byte is lost: the decoder
	 * rejects that frame). */
	while (REG32(USART1 + USART_SR) & USART_SR_RXNE)
		fw_isr_uart_rx((uint8_t)REG32(USART1 + USART_DR));
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

__attribute__((section(".vectors"), used)) static const cm_vector vectors[16 + 60] = {
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
	[16 + TIM2_IRQ] = tim2_isr,
	[16 + USART1_IRQ] = usart1_isr,
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
