/*
 * logwrite.h - write decoded logs in the DESIGN.md section 7 format:
 * CSV (header of SI-suffixed column names, one row per sample, %.17g so the
 * doubles round-trip) and the JSON sidecar <name>.json beside it.
 *
 * Both files are written to temporary names in the destination directory and
 * renamed into place only when complete: a failed run leaves no half log.
 */
#ifndef HD_LOGWRITE_H
#define HD_LOGWRITE_H

#include <stddef.h>
#include <stdint.h>

/* Sidecar path of a CSV path: "x/run.csv" -> "x/run.json" (extension replaced
 * or appended).  0 ok, -1 if it does not fit. */
int hd_log_sidecar_path(const char *csv_path, char *out, size_t cap);

/* Write rows (n_rows x n_cols, row-major) under the column names and the
 * sidecar JSON text (a complete object).  0 ok, -1 with one line in err. */
int hd_log_write(const char *csv_path, const char *const *names, int32_t n_cols,
                 const double *rows, int64_t n_rows, const char *sidecar_json,
                 char *err, size_t errlen);

/* Append a JSON string literal (quoted, escaped) to buf at *len. */
void hd_json_str(char *buf, size_t cap, size_t *len, const char *s);
/* printf-append to buf at *len (truncates safely; *len saturates at cap-1). */
void hd_json_add(char *buf, size_t cap, size_t *len, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

#endif /* HD_LOGWRITE_H */
