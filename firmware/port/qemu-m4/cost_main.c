/*
 * cost_main.c - instruction-cost image for the emulated Cortex-M4.
 *
 * Calls hd_gv_cost_mark() twice back to back (the baseline: the mark's own
 * `bx lr` plus the `bl`), then, for every registered kernel that has a
 * cost() function, prints "COST <kernel>" and calls cost(), which brackets
 * one representative call between two marks.  The QEMU plugin
 * tools/qemu-insncount counts executed instructions and logs the count at
 * each mark; tests/bench/10_cm4_cost.sh subtracts the baseline.
 */
#include "gv_registry.h"
#include "semihost.h"

int main(void)
{
    uint32_t m, k;
    hd_sh_write0("BASELINE\n");
    hd_gv_cost_mark();
    hd_gv_cost_mark();
    for (m = 0u; m < hd_gv_n_modules; m++) {
        for (k = 0u; k < *hd_gv_modules[m].count; k++) {
            const hd_gv_kernel_t *kn = &hd_gv_modules[m].kernels[k];
            if (kn->cost != 0) {
                char buf[160];
                uint32_t pos = 0u;
                hd_sh_cat(buf, sizeof buf, &pos, "COST ");
                hd_sh_cat(buf, sizeof buf, &pos, kn->name);
                hd_sh_cat(buf, sizeof buf, &pos, "\n");
                hd_sh_write0(buf);
                kn->cost();
            }
        }
    }
    hd_sh_write0("DONE\n");
    return 0;
}
