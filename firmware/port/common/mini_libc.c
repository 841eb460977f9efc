/*
 * mini_libc.c - the four functions gcc may emit calls to even with
 * -ffreestanding (struct copies, large initialisers): memcpy, memmove,
 * memset, memcmp.  The one C library shim of the Cortex-M4 images: the QEMU
 * images (mk/golden.mk) and the STM32G474 image (mk/firmware.mk) link no libc.
 * Byte loops; both builds compile this file with
 * -fno-tree-loop-distribute-patterns so gcc does not turn them back into
 * calls to themselves.
 */
#include <stddef.h>
#include <stdint.h>

void *memcpy(void *dst, const void *src, size_t n);
void *memmove(void *dst, const void *src, size_t n);
void *memset(void *dst, int c, size_t n);
int memcmp(const void *a, const void *b, size_t n);

void *memcpy(void *dst, const void *src, size_t n)
{
    uint8_t *d = dst;
    const uint8_t *s = src;
    while (n > 0u) {
        *d++ = *s++;
        n--;
    }
    return dst;
}

void *memmove(void *dst, const void *src, size_t n)
{
    uint8_t *d = dst;
    const uint8_t *s = src;
    if ((uintptr_t)d < (uintptr_t)s) {
        while (n > 0u) {
            *d++ = *s++;
            n--;
        }
    } else {
        while (n > 0u) {
            n--;
            d[n] = s[n];
        }
    }
    return dst;
}

void *memset(void *dst, int c, size_t n)
{
    uint8_t *d = dst;
    const uint8_t v = (uint8_t)(uint32_t)c;
    while (n > 0u) {
        *d++ = v;
        n--;
    }
    return dst;
}

int memcmp(const void *a, const void *b, size_t n)
{
    const uint8_t *x = a;
    const uint8_t *y = b;
    size_t i;
    for (i = 0u; i < n; i++) {
        if (x[i] != y[i]) {
            return (x[i] < y[i]) ? -1 : 1;
        }
    }
    return 0;
}
