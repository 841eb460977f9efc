/*
 * phase_main.c - per-phase instruction cost of hd_app_step on the emulated
 * Cortex-M4 (tests/bench/15_phase_cost.sh).
 *
 * Runs the cost() of ONE golden kernel (HD_PHASE_KERNEL, a string given at
 * compile time) from the registry.  The image is linked with a copy of
 * hd_app.c built with HD_APP_PHASE_PROBE and hd_app_phase_mark renamed to
 * hd_gv_cost_mark, so the QEMU plugin logs a mark at the kernel's two marks
 * and between the phases of every hd_app_step; the script reads the phases of
 * the measured (last) step from the tail of the mark log.
 */
#include "gv_registry.h"
#include "semihost.h"

#ifndef HD_PHASE_KERNEL
#error "HD_PHASE_KERNEL (kernel name string) must be defined"
#endif

static int32_t same(const char *x, const char *y)
{
    while (*x != '\0' && *x == *y) {
        x++;
        y++;
    }
    return (*x == *y) ? 1 : 0;
}

int main(void)
{
    uint32_t m, k;
    hd_gv_cost_mark();
    hd_gv_cost_mark();
    for (m = 0u; m < hd_gv_n_modules; m++) {
        for (k = 0u; k < *hd_gv_modules[m].count; k++) {
            const hd_gv_kernel_t *kn = &hd_gv_modules[m].kernels[k];
            if (kn->cost != 0 && same(kn->name, HD_PHASE_KERNEL) != 0) {
                kn->cost();
                hd_sh_write0("DONE\n");
                return 0;
            }
        }
    }
    hd_sh_write0("NOKERNEL\n");
    return 1;
}
