/* startup_nrf51.c: how the C board starts on the nRF51822 (make -C firmware board-m0, with nrf51822_s110.ld).
 *
 * The vector table sits at the application's base (0x18000), where the S110 SoftDevice's MBR forwards the reset and
 * the interrupts: word 0 the initial stack pointer (the top of RAM), word 1 the reset handler, then the Cortex-M0's
 * exceptions (ARMv6-M Architecture Reference Manual, B1.5.2 "Exception number definition": NMI 2, HardFault 3,
 * SVCall 11, PendSV 14, SysTick 15) and the nRF51's interrupts from 16 on (nRF51 Series Reference Manual v3.0,
 * "Instantiation", the ID column: POWER_CLOCK 0, RADIO 1, UART0 2 ... RTC1 17). The table stops at UART0, the last
 * interrupt the board enables (hal_m0.c: RTC1's compare only wakes the CPU from WFE, SEVONPEND, with no handler);
 * a team that enables another one extends it. Reset_Handler copies .data's initial values from flash, zeroes .bss
 * and calls qb_m0_main (hal_m0.c), which never returns.
 */
#include <stdint.h>

extern uint32_t __data_load__[], __data_start__[], __data_end__[], __bss_start__[], __bss_end__[], __stack_top__[];

void Reset_Handler(void);
void qb_m0_main(void);
void UART0_IRQHandler(void);
static void fault(void);

__attribute__((section(".isr_vector"), used)) static const uintptr_t VECTORS[16 + 3] = {
    (uintptr_t)__stack_top__,
    (uintptr_t)Reset_Handler,
    (uintptr_t)fault, /* NMI */
    (uintptr_t)fault, /* HardFault */
    0, 0, 0, 0, 0, 0, 0,
    (uintptr_t)fault, /* SVCall */
    0, 0,
    (uintptr_t)fault, /* PendSV */
    (uintptr_t)fault, /* SysTick */
    (uintptr_t)fault, /* 0 POWER_CLOCK */
    (uintptr_t)fault, /* 1 RADIO */
    (uintptr_t)UART0_IRQHandler, /* 2 UART0 */
};

void Reset_Handler(void)
{
    uint32_t *src = __data_load__, *dst = __data_start__;
    while (dst < __data_end__)
        *dst++ = *src++;
    for (dst = __bss_start__; dst < __bss_end__;)
        *dst++ = 0;
    qb_m0_main();
    fault();
}

/* An exception nothing handles: stop here (a debugger finds the board in this loop; the motors stay as they were
 * last set, so a team's ESC driver should stop them on a missing pulse). */
static void fault(void)
{
    for (;;) {
    }
}
