/*
 * toml_lite.h - a small, strict reader for the TOML subset hdservo uses
 * (scenario and axis files).  Simulator side (double precision), not firmware.
 *
 * Supported:
 *   # comments (whole line or after a value)
 *   [section]  [section.sub]        tables (bare keys, dotted)
 *   [[name]]                         arrays of tables: keys become "name.N.key"
 *   key = value   a.b = value        bare or "quoted" keys, dotted keys
 *   values: numbers (int / decimal / exponent, '_' between digits, +inf/-inf;
 *           nan is refused), "basic strings" with \" \\ \n \t \r escapes,
 *           'literal strings', true / false, [arrays] of numbers or of
 *           strings (may span lines, trailing comma allowed).
 * Not supported (refused with an error): inline tables, dates, multi-line
 * strings, hex/octal/binary integers, mixed arrays, nested arrays.
 *
 * Every entry is stored under its full dotted key ("plant.stiffness.k1_Nm_per_rad",
 * "fault.0.t_s").  Bounds: file <= HD_TOML_MAX_FILE bytes, keys <= HD_TOML_MAX_KEY
 * characters, strings <= HD_TOML_MAX_STR, <= HD_TOML_MAX_ENTRIES entries,
 * arrays <= HD_TOML_MAX_ARRAY elements.  Every error is one line
 * "FILE:LINE:COL: expected ..." written into the caller's buffer.
 */
#ifndef HD_TOML_LITE_H
#define HD_TOML_LITE_H

#include <stddef.h>
#include <stdint.h>

#define HD_TOML_MAX_FILE    (4u * 1024u * 1024u)
#define HD_TOML_MAX_KEY     255u
#define HD_TOML_MAX_STR     1023u
#define HD_TOML_MAX_ENTRIES 8192u
#define HD_TOML_MAX_ARRAY   1000000u
#define HD_TOML_MAX_TABLES  4096u   /* entries of one [[array-of-tables]] */

typedef enum {
    HD_TOML_NUMBER = 1,
    HD_TOML_STRING,
    HD_TOML_BOOL,
    HD_TOML_NUM_ARRAY,
    HD_TOML_STR_ARRAY
} hd_toml_type_t;

typedef struct {
    char *key;            /* full dotted key */
    hd_toml_type_t type;
    double num;           /* HD_TOML_NUMBER */
    int is_integer;       /* number was written without '.', 'e' or inf */
    int boolean;          /* HD_TOML_BOOL: 0 or 1 */
    char *str;            /* HD_TOML_STRING */
    double *arr;          /* HD_TOML_NUM_ARRAY */
    char **sarr;          /* HD_TOML_STR_ARRAY */
    size_t n;             /* elements in arr / sarr */
    int32_t line, col;    /* where the value starts (1-based) */
    int used;             /* set by the hd_toml_get* accessors */
} hd_toml_entry_t;

typedef struct {
    char *file;           /* name used in error messages */
    hd_toml_entry_t *e;
    size_t n, cap;
    /* arrays of tables: name and count */
    char **aot_name;
    size_t *aot_count;
    size_t n_aot, cap_aot;
} hd_toml_doc_t;

/* Parse text[0..len).  Returns 0, or -1 with a one-line message in err.
 * On error the document is left empty (nothing to free, but freeing is safe). */
int hd_toml_parse(const char *text, size_t len, const char *fname,
                  hd_toml_doc_t *doc, char *err, size_t errlen);
/* Read and parse a file (error "FILE: cannot read: ..." if it cannot be read). */
int hd_toml_load(const char *path, hd_toml_doc_t *doc, char *err, size_t errlen);
void hd_toml_free(hd_toml_doc_t *doc);

/* Lookup by full dotted key; NULL if absent.  Marks the entry used. */
hd_toml_entry_t *hd_toml_find(hd_toml_doc_t *doc, const char *key);
/* Number of [[name]] tables (0 if none). */
size_t hd_toml_table_count(const hd_toml_doc_t *doc, const char *name);

/* Typed getters: return 1 if found and of the right type, 0 if absent,
 * -1 (with a one-line error naming file:line:col) if present with a wrong type. */
int hd_toml_get_number(hd_toml_doc_t *doc, const char *key, double *out,
                       char *err, size_t errlen);
int hd_toml_get_string(hd_toml_doc_t *doc, const char *key, const char **out,
                       char *err, size_t errlen);
int hd_toml_get_bool(hd_toml_doc_t *doc, const char *key, int *out,
                     char *err, size_t errlen);
int hd_toml_get_num_array(hd_toml_doc_t *doc, const char *key, const double **out,
                          size_t *n, char *err, size_t errlen);

/* The first entry whose key starts with prefix and was never looked up;
 * NULL if every such entry was used.  (Catches misspelt keys.) */
const hd_toml_entry_t *hd_toml_first_unused(const hd_toml_doc_t *doc, const char *prefix);

/* One-line "FILE:LINE:COL: msg" for an entry. */
void hd_toml_entry_error(const hd_toml_doc_t *doc, const hd_toml_entry_t *e,
                         char *err, size_t errlen, const char *msg);

#endif /* HD_TOML_LITE_H */
