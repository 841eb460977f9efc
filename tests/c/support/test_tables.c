/*
 * test_tables.c - fixtures shared by the C unit tests (test_tables.h).
 */
#include "test_tables.h"
#include <string.h>

void test_everett_table(hd_preisach_table_t *t, uint32_t levels, uint32_t version, int32_t scale)
{
    uint32_t i, j;
    memset(t, 0, sizeof *t);
    t->version = version;
    t->levels = levels;
    t->sub_bits = 1u;
    t->in_shift = 10u;
    t->u0 = -4096;
    t->unit = HD_PREISACH_UNIT_TORQUE_TWIST;
    for (i = 0u; i < levels; i++) {
        for (j = 0u; j <= i; j++) {
            t->e[i * (i + 1u) / 2u + j] = scale * (int32_t)((i - j) * (i - j + 1u));
        }
    }
    hd_preisach_seal(t);
}
