/* Reset and exception vectors of the STM32F405: copy .data, zero .bss (not .noinit), run main.
 * Every exception and unused interrupt makes the outputs safe and waits for the watchdog reset. */
#include <stdint.h>

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
extern int main(void);
extern void board_fault(void);
extern void TIM6_DAC_IRQHandler(void);

void Reset_Handler(void)
{
    const uint32_t *src = &_sidata;
    for (uint32_t *dst = &_sdata; dst < &_edata;)
        *dst++ = *src++;
    for (uint32_t *dst = &_sbss; dst < &_ebss;)
        *dst++ = 0;
    main();
    board_fault();
}

static void fault_handler(void)
{
    board_fault();
}

#define VECTORS (16 + 82)      /* Cortex-M4 exceptions + the F405's 82 interrupts */
#define IRQ(n) (16 + (n))

__attribute__((section(".isr_vector"), used)) static void (*const vectors[VECTORS])(void) = {
    [0] = (void (*)(void))&_estack,
    [1] = Reset_Handler,
    [2 ... IRQ(54) - 1] = fault_handler,        /* (GNU range designators) */
    [IRQ(54)] = TIM6_DAC_IRQHandler,
    [IRQ(54) + 1 ... VECTORS - 1] = fault_handler,
};
