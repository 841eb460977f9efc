/*
 * test_tables.h - fixtures shared by the C unit tests (linked into every test binary
 * from tests/c/support/).
 */
#ifndef TEST_TABLES_H
#define TEST_TABLES_H

#include <stdint.h>
#include "hd_preisach.h"

/** A sealed L-level Everett table E[i][j] = scale (i - j)(i - j + 1) (zero diagonal,
 *  a non-negative density), lattice: sub_bits 1, in_shift 10, u0 -4096, torque -> twist. */
void test_everett_table(hd_preisach_table_t *t, uint32_t levels, uint32_t version, int32_t scale);

#endif
