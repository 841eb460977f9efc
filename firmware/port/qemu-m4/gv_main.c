/*
 * gv_main.c - golden-vector replay on the emulated Cortex-M4.
 *
 * For every registered kernel (build/golden/gv_registry.c, same order as
 * the host generator) runs run() on the host-generated inputs and compares
 * every output word with the host result (build/golden/gv_data.c).  Prints
 *   PASS <kernel> <count>
 *   FAIL <kernel> vector <i> word <j> got 0x.. want 0x..
 * per kernel and "DONE kernels <n> failed <f>"; returns 1 if any failed.
 */
#include "gv_registry.h"
#include "semihost.h"

#define LINE 200u

static void line3(const char *a, const char *b, const char *c)
{
    char buf[LINE];
    uint32_t pos = 0u;
    hd_sh_cat(buf, LINE, &pos, a);
    hd_sh_cat(buf, LINE, &pos, b);
    hd_sh_cat(buf, LINE, &pos, c);
    hd_sh_write0(buf);
}

static uint32_t check_kernel(const hd_gv_kernel_t *kn, const hd_gv_data_t *d)
{
    char buf[LINE];
    uint32_t pos = 0u;
    uint32_t w;
    const uint32_t words = kn->count * kn->n_out;

    if (!hd_sh_streq(kn->name, d->name) || kn->n_in != d->n_in || kn->n_out != d->n_out
        || kn->count != d->count || words > hd_gv_outbuf_words) {
        line3("FAIL ", kn->name, " registry and generated data disagree (stale build?)\n");
        return 1u;
    }
    /* poison the buffer: a run() that leaves an output unwritten fails */
    for (w = 0u; w < words; w++) {
        hd_gv_outbuf[w] = 0x5A5A5A5A;
    }
    kn->run(d->in, hd_gv_outbuf, kn->count);
    for (w = 0u; w < words; w++) {
        if (hd_gv_outbuf[w] != d->out[w]) {
            hd_sh_cat(buf, LINE, &pos, "FAIL ");
            hd_sh_cat(buf, LINE, &pos, kn->name);
            hd_sh_cat(buf, LINE, &pos, " vector ");
            hd_sh_cat_u32(buf, LINE, &pos, w / kn->n_out);
            hd_sh_cat(buf, LINE, &pos, " word ");
            hd_sh_cat_u32(buf, LINE, &pos, w % kn->n_out);
            hd_sh_cat(buf, LINE, &pos, " got ");
            hd_sh_cat_hex(buf, LINE, &pos, hd_gv_s2u(hd_gv_outbuf[w]));
            hd_sh_cat(buf, LINE, &pos, " want ");
            hd_sh_cat_hex(buf, LINE, &pos, hd_gv_s2u(d->out[w]));
            hd_sh_cat(buf, LINE, &pos, "\n");
            hd_sh_write0(buf);
            return 1u;
        }
    }
    hd_sh_cat(buf, LINE, &pos, "PASS ");
    hd_sh_cat(buf, LINE, &pos, kn->name);
    hd_sh_cat(buf, LINE, &pos, " ");
    hd_sh_cat_u32(buf, LINE, &pos, kn->count);
    hd_sh_cat(buf, LINE, &pos, "\n");
    hd_sh_write0(buf);
    return 0u;
}

int main(void)
{
    char buf[LINE];
    uint32_t pos = 0u;
    uint32_t m, k, idx = 0u, failed = 0u;

    for (m = 0u; m < hd_gv_n_modules; m++) {
        for (k = 0u; k < *hd_gv_modules[m].count; k++, idx++) {
            const hd_gv_kernel_t *kn = &hd_gv_modules[m].kernels[k];
            if (idx >= hd_gv_data_count) {
                line3("FAIL ", kn->name, " has no generated data (stale build?)\n");
                failed++;
                continue;
            }
            failed += check_kernel(kn, &hd_gv_data[idx]);
        }
    }
    if (idx != hd_gv_data_count) {
        hd_sh_write0("FAIL generated data has more kernels than the registry (stale build?)\n");
        failed++;
    }
    hd_sh_cat(buf, LINE, &pos, "DONE kernels ");
    hd_sh_cat_u32(buf, LINE, &pos, idx);
    hd_sh_cat(buf, LINE, &pos, " failed ");
    hd_sh_cat_u32(buf, LINE, &pos, failed);
    hd_sh_cat(buf, LINE, &pos, "\n");
    hd_sh_write0(buf);
    return (failed != 0u) ? 1 : 0;
}
