/*
 * semihost.c - ARM semihosting calls (bkpt 0xab, r0 = operation, r1 =
 * argument) for QEMU -semihosting-config enable=on,target=native.
 */
#include "semihost.h"

#define SYS_WRITE0        0x04u
#define SYS_EXIT          0x18u
#define SYS_EXIT_EXTENDED 0x20u
#define ADP_STOPPED_APPLICATION_EXIT 0x20026u
#define ADP_STOPPED_RUNTIME_ERROR    0x20023u

static uint32_t sh_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void hd_sh_write0(const char *s)
{
    (void)sh_call(SYS_WRITE0, s);
}

void hd_sh_exit(uint32_t code)
{
    static volatile uint32_t block[2];
    block[0] = ADP_STOPPED_APPLICATION_EXIT;
    block[1] = code;
    (void)sh_call(SYS_EXIT_EXTENDED, (const void *)block);
    /* not supported by the host: plain SYS_EXIT gives rc 0 or 1 */
    (void)sh_call(SYS_EXIT, (const void *)(uintptr_t)((code == 0u) ? ADP_STOPPED_APPLICATION_EXIT
                                                                    : ADP_STOPPED_RUNTIME_ERROR));
    for (;;) {
    }
}

void hd_sh_cat(char *buf, uint32_t cap, uint32_t *pos, const char *s)
{
    while (*s != '\0' && *pos + 1u < cap) {
        buf[*pos] = *s;
        (*pos)++;
        s++;
    }
    buf[*pos] = '\0';
}

void hd_sh_cat_u32(char *buf, uint32_t cap, uint32_t *pos, uint32_t v)
{
    char tmp[11];
    uint32_t n = 0u;
    do {
        tmp[n] = (char)('0' + (v % 10u));
        n++;
        v /= 10u;
    } while (v != 0u);
    while (n > 0u && *pos + 1u < cap) {
        n--;
        buf[*pos] = tmp[n];
        (*pos)++;
    }
    buf[*pos] = '\0';
}

void hd_sh_cat_hex(char *buf, uint32_t cap, uint32_t *pos, uint32_t v)
{
    static const char digits[] = "0123456789abcdef";
    uint32_t i;
    hd_sh_cat(buf, cap, pos, "0x");
    for (i = 0u; i < 8u && *pos + 1u < cap; i++) {
        buf[*pos] = digits[(v >> (28u - 4u * i)) & 0xFu];
        (*pos)++;
    }
    buf[*pos] = '\0';
}

int hd_sh_streq(const char *a, const char *b)
{
    while (*a != '\0' && *a == *b) {
        a++;
        b++;
    }
    return *a == *b;
}
