/*
 * hd_nofloat.h - force-included (gcc -include) into every firmware/ source.
 *
 * The drive's control code is integer-only (DESIGN.md section 3): any use of
 * the floating-point types after this point is a compile error on both the
 * host gcc and arm-none-eabi-gcc.  The system headers the core may use
 * (stdint.h, stdbool.h, stddef.h under -std=c99) are included first so that
 * their own declarations are not poisoned.
 */
#ifndef HD_NOFLOAT_H
#define HD_NOFLOAT_H
#include <stdint.h>
#include <stdbool.h>
#include <stddef.h>
#pragma GCC poison float double
#endif
