/*
 * semihost.h - minimal ARM semihosting for the QEMU test images: write a
 * string (SYS_WRITE0) and exit with a code (SYS_EXIT_EXTENDED, falling back
 * to SYS_EXIT), plus the number formatting the images need (no libc).
 */
#ifndef HD_SEMIHOST_H
#define HD_SEMIHOST_H

#include <stdint.h>

void hd_sh_write0(const char *s);
/* Exit QEMU with `code` (0..255 reaches the shell as the exit status). */
void hd_sh_exit(uint32_t code) __attribute__((noreturn));
/* Append helpers: write into buf at *pos (bounded by cap, NUL-terminated). */
void hd_sh_cat(char *buf, uint32_t cap, uint32_t *pos, const char *s);
void hd_sh_cat_u32(char *buf, uint32_t cap, uint32_t *pos, uint32_t v);
void hd_sh_cat_hex(char *buf, uint32_t cap, uint32_t *pos, uint32_t v);
int hd_sh_streq(const char *a, const char *b);

#endif /* HD_SEMIHOST_H */
