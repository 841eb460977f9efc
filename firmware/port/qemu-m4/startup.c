/*
 * startup.c - reset handler and vector table of the QEMU mps2-an386 test
 * images: copy .data, zero .bss, run main(), pass its return value to the
 * semihosting exit.  Every fault exits with a distinct code (100 + vector)
 * so a crash can never look like a pass or hang until the timeout.
 */
#include <stdint.h>
#include "semihost.h"

extern uint32_t _sidata, _sdata, _edata, _sbss, _ebss, _estack;
int main(void);
void hd_m4_reset_handler(void);

void hd_m4_reset_handler(void)
{
    const uint32_t *src = &_sidata;
    uint32_t *dst = &_sdata;
    while (dst < &_edata) {
        *dst = *src;
        dst++;
        src++;
    }
    for (dst = &_sbss; dst < &_ebss; dst++) {
        *dst = 0u;
    }
    hd_sh_exit((uint32_t)main());
}

static void fault(uint32_t vec)
{
    hd_sh_write0("FAULT: Cortex-M4 exception, exiting\n");
    hd_sh_exit(100u + vec);
}

static void nmi_handler(void) { fault(2u); }
static void hardfault_handler(void) { fault(3u); }
static void memmanage_handler(void) { fault(4u); }
static void busfault_handler(void) { fault(5u); }
static void usagefault_handler(void) { fault(6u); }
static void default_handler(void) { fault(15u); }

typedef void (*hd_vector_t)(void);

__attribute__((section(".isr_vector"), used))
static const hd_vector_t hd_vectors[16] = {
    (hd_vector_t)(uintptr_t)&_estack,
    hd_m4_reset_handler,
    nmi_handler,
    hardfault_handler,
    memmanage_handler,
    busfault_handler,
    usagefault_handler,
    0, 0, 0, 0,
    default_handler,     /* SVCall */
    default_handler,     /* DebugMonitor */
    0,
    default_handler,     /* PendSV */
    default_handler,     /* SysTick */
};
