/* Bits every Cortex-M3 board port shares: register access, NVIC, SysTick, sleep, and the
 * C runtime start (copy .data, zero .bss) called from each board's reset handler. */
#ifndef FACESCAN_BOARDS_CORTEX_M_H
#define FACESCAN_BOARDS_CORTEX_M_H

#include <stdint.h>

#define REG32(addr) (*(volatile uint32_t *)(uintptr_t)(addr))

#define SYST_CSR 0xe000e010u
#define SYST_RVR 0xe000e014u
#define SYST_CVR 0xe000e018u
#define SYST_CSR_ENABLE (1u << 0)
#define SYST_CSR_TICKINT (1u << 1)
#define SYST_CSR_CLKSOURCE (1u << 2)
#define NVIC_ISER0 0xe000e100u
#define SCB_AIRCR 0xe000ed0cu

static inline void cm_nvic_enable(unsigned irq)
{
	REG32(NVIC_ISER0 + 4u * (irq / 32u)) = 1u << (irq % 32u);
}

static inline void cm_wfi(void)
{
	__asm__ volatile("wfi");
}

static inline void cm_irq_enable(void)
{
	__asm__ volatile("cpsie i" ::: "memory");
}

/* Copy initialised data from flash and zero .bss (symbols from cortex-m.ld). */
static inline void cm_crt_init(void)
{
	extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss;
	const uint32_t *src = &_sidata;
	for (uint32_t *dst = &_sdata; dst < &_edata;)
		*dst++ = *src++;
	for (uint32_t *dst = &_sbss; dst < &_ebss;)
		*dst++ = 0;
}

typedef void (*cm_vector)(void);

#endif
