/*
 * fuzz_common.h - helpers shared by the libFuzzer targets in tests/fuzz/.
 *
 * A target reads its input as a little byte stream; when the stream is
 * exhausted every reader returns 0, so any input (empty included) is valid
 * and the target never reads past the buffer itself.  A violated invariant
 * calls FUZZ_ASSERT, which aborts: libFuzzer reports it as a crash and saves
 * the input (crash-<sha1>) for the regression corpus.
 */
#ifndef FUZZ_COMMON_H
#define FUZZ_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#define FUZZ_ASSERT(c)                                                              \
    do {                                                                            \
        if (!(c)) {                                                                 \
            fprintf(stderr, "%s:%d: invariant failed: %s\n", __FILE__, __LINE__, #c); \
            abort();                                                                \
        }                                                                           \
    } while (0)

typedef struct {
    const uint8_t *p;
    size_t n, i;
} fz_stream_t;

static inline void fz_init(fz_stream_t *s, const uint8_t *p, size_t n)
{
    s->p = p;
    s->n = n;
    s->i = 0;
}
static inline size_t fz_left(const fz_stream_t *s) { return s->n - s->i; }
static inline uint8_t fz_u8(fz_stream_t *s) { return s->i < s->n ? s->p[s->i++] : 0u; }
static inline uint16_t fz_u16(fz_stream_t *s)
{
    const uint16_t lo = fz_u8(s);
    return (uint16_t)(lo | ((uint16_t)fz_u8(s) << 8));
}
static inline uint32_t fz_u32(fz_stream_t *s)
{
    const uint32_t lo = fz_u16(s);
    return lo | ((uint32_t)fz_u16(s) << 16);
}
static inline int32_t fz_i32(fz_stream_t *s)
{
    const uint32_t u = fz_u32(s);
    return (u > 0x7FFFFFFFu) ? -(int32_t)(~u) - 1 : (int32_t)u;
}

#endif
