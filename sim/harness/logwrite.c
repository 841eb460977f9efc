/*
 * logwrite.c - CSV + JSON sidecar writer (see logwrite.h).
 */
#include "logwrite.h"
#include "sim_err.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>


void hd_json_add(char *buf, size_t cap, size_t *len, const char *fmt, ...)
{
    va_list ap;
    if (*len + 1 >= cap) return;
    va_start(ap, fmt);
    int n = vsnprintf(buf + *len, cap - *len, fmt, ap);
    va_end(ap);
    if (n < 0) return;
    *len += (size_t)n;
    if (*len >= cap) *len = cap - 1;
}

void hd_json_str(char *buf, size_t cap, size_t *len, const char *s)
{
    hd_json_add(buf, cap, len, "\"");
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') hd_json_add(buf, cap, len, "\\%c", c);
        else if (c < 0x20) hd_json_add(buf, cap, len, "\\u%04x", c);
        else hd_json_add(buf, cap, len, "%c", c);
    }
    hd_json_add(buf, cap, len, "\"");
}

int hd_log_sidecar_path(const char *csv_path, char *out, size_t cap)
{
    size_t n = strlen(csv_path);
    const char *slash = strrchr(csv_path, '/');
    const char *dot = strrchr(csv_path, '.');
    size_t stem = (dot && (!slash || dot > slash + 1)) ? (size_t)(dot - csv_path) : n;
    if (stem + 6 > cap) return -1;
    memcpy(out, csv_path, stem);
    memcpy(out + stem, ".json", 6);
    return 0;
}

/* temp name in the same directory: "<path>.tmp.<pid>" */
static int tmp_name(const char *path, char *out, size_t cap)
{
    int n = snprintf(out, cap, "%s.tmp.%ld", path, (long)getpid());
    return (n < 0 || (size_t)n >= cap) ? -1 : 0;
}

static int write_csv(FILE *f, const char *const *names, int32_t n_cols, const double *rows, int64_t n_rows)
{
    for (int32_t j = 0; j < n_cols; j++)
        if (fprintf(f, "%s%s", j ? "," : "", names[j]) < 0) return -1;
    if (fputc('\n', f) == EOF) return -1;
    char line[64 * 32];
    for (int64_t i = 0; i < n_rows; i++) {
        const double *r = rows + i * n_cols;
        size_t len = 0;
        for (int32_t j = 0; j < n_cols; j++) {
            if (len + 32 >= sizeof line) {
                if (fwrite(line, 1, len, f) != len) return -1;
                len = 0;
            }
            int w = snprintf(line + len, sizeof line - len, j ? ",%.17g" : "%.17g", r[j]);
            if (w < 0) return -1;
            len += (size_t)w;
        }
        line[len++] = '\n';
        if (fwrite(line, 1, len, f) != len) return -1;
    }
    return 0;
}

int hd_log_write(const char *csv_path, const char *const *names, int32_t n_cols,
                 const double *rows, int64_t n_rows, const char *sidecar_json,
                 char *err, size_t errlen)
{
    char side[4096], tcsv[4200], tside[4200];
    if (hd_log_sidecar_path(csv_path, side, sizeof side) || tmp_name(csv_path, tcsv, sizeof tcsv) ||
        tmp_name(side, tside, sizeof tside)) {
        sim_set_err(err, errlen, "%s: path too long", csv_path);
        return -1;
    }
    for (int64_t i = 0; i < n_rows * (int64_t)n_cols; i++) {
        if (!isfinite(rows[i])) {
            sim_set_err(err, errlen, "%s: refusing to write a non-finite value (row %lld, column %s): the simulation diverged",
                    csv_path, (long long)(i / n_cols), names[i % n_cols]);
            return -1;
        }
    }
    FILE *f = fopen(tcsv, "w");
    if (!f) {
        sim_set_err(err, errlen, "%s: cannot write: %s", csv_path, strerror(errno));
        return -1;
    }
    /* big buffer: the CSV is written in one pass */
    setvbuf(f, NULL, _IOFBF, 1 << 20);
    int bad = write_csv(f, names, n_cols, rows, n_rows);
    if (fclose(f) != 0) bad = -1;
    if (bad) {
        remove(tcsv);
        sim_set_err(err, errlen, "%s: write failed: %s", csv_path, strerror(errno));
        return -1;
    }
    f = fopen(tside, "w");
    if (!f) {
        remove(tcsv);
        sim_set_err(err, errlen, "%s: cannot write: %s", side, strerror(errno));
        return -1;
    }
    size_t sl = strlen(sidecar_json);
    bad = (fwrite(sidecar_json, 1, sl, f) != sl);
    if (fclose(f) != 0) bad = 1;
    if (bad) {
        remove(tcsv);
        remove(tside);
        sim_set_err(err, errlen, "%s: write failed", side);
        return -1;
    }
    if (rename(tcsv, csv_path) != 0) {
        int e = errno;
        remove(tcsv);
        remove(tside);
        sim_set_err(err, errlen, "%s: cannot write: %s", csv_path, strerror(e));
        return -1;
    }
    if (rename(tside, side) != 0) {
        int e = errno;
        remove(tside);
        remove(csv_path);
        sim_set_err(err, errlen, "%s: cannot write: %s", side, strerror(e));
        return -1;
    }
    return 0;
}
