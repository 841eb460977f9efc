/*
 * hd_co_util.h - byte helpers of the CANopen stack (no <string.h>: the
 * Cortex-M4 build is freestanding and newlib's headers are not included).
 */
#ifndef HD_CO_UTIL_H
#define HD_CO_UTIL_H

#include <stddef.h>
#include <stdint.h>

static inline void hd_co_copy(void *dst, const void *src, size_t n)
{
    uint8_t *d = (uint8_t *)dst;
    const uint8_t *s = (const uint8_t *)src;
    if (d == s || n == 0u) {
        return;
    }
    if (d < s) {
        for (size_t i = 0u; i < n; i++) d[i] = s[i];
    } else {
        for (size_t i = n; i > 0u; i--) d[i - 1u] = s[i - 1u];
    }
}

static inline void hd_co_fill(void *dst, uint8_t v, size_t n)
{
    uint8_t *d = (uint8_t *)dst;
    for (size_t i = 0u; i < n; i++) d[i] = v;
}

static inline int hd_co_diff(const void *a, const void *b, size_t n)
{
    const uint8_t *x = (const uint8_t *)a, *y = (const uint8_t *)b;
    for (size_t i = 0u; i < n; i++) {
        if (x[i] != y[i]) return 1;
    }
    return 0;
}

static inline size_t hd_co_strlen(const char *s)
{
    size_t n = 0u;
    while (s[n] != '\0') n++;
    return n;
}

#endif /* HD_CO_UTIL_H */
