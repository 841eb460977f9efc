/*
 * fuzz_toml.c - the C TOML reader of host-side files (sim/harness/toml_lite):
 * scenario and axis files.  Any byte string must either parse or give exactly
 * one error line "FILE:LINE:COL: ..." (no newline inside, never empty); a
 * parsed document is walked through every accessor.
 */
#include <string.h>
#include "fuzz_common.h"
#include "toml_lite.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    hd_toml_doc_t doc;
    char err[512];
    memset(&doc, 0, sizeof doc);
    err[0] = '\0';
    const int rc = hd_toml_parse((const char *)data, size, "fuzz.toml", &doc, err, sizeof err);
    if (rc != 0) {
        FUZZ_ASSERT(rc == -1);
        FUZZ_ASSERT(strncmp(err, "fuzz.toml", 9) == 0);
        FUZZ_ASSERT(strchr(err, '\n') == NULL);
        FUZZ_ASSERT(doc.n == 0);
        hd_toml_free(&doc);
        return 0;
    }
    /* every entry is reachable by its key and has a sane shape */
    for (size_t i = 0; i < doc.n; i++) {
        hd_toml_entry_t *e = &doc.e[i];
        FUZZ_ASSERT(e->key != NULL && strlen(e->key) <= HD_TOML_MAX_KEY);
        FUZZ_ASSERT(e->line >= 1 && e->col >= 1);
        FUZZ_ASSERT(hd_toml_find(&doc, e->key) != NULL);
        double d;
        const char *s;
        int b;
        const double *arr;
        size_t n;
        char e2[256];
        int r = hd_toml_get_number(&doc, e->key, &d, e2, sizeof e2);
        FUZZ_ASSERT(r == (e->type == HD_TOML_NUMBER ? 1 : -1));
        if (r == 1) {
            FUZZ_ASSERT(d == d); /* nan is refused by the reader */
        }
        r = hd_toml_get_string(&doc, e->key, &s, e2, sizeof e2);
        FUZZ_ASSERT(r == (e->type == HD_TOML_STRING ? 1 : -1));
        if (r == 1) {
            FUZZ_ASSERT(strlen(s) <= HD_TOML_MAX_STR);
        }
        r = hd_toml_get_bool(&doc, e->key, &b, e2, sizeof e2);
        FUZZ_ASSERT(r == (e->type == HD_TOML_BOOL ? 1 : -1));
        r = hd_toml_get_num_array(&doc, e->key, &arr, &n, e2, sizeof e2);
        FUZZ_ASSERT(r == (e->type == HD_TOML_NUM_ARRAY ? 1 : -1));
        if (r == 1) {
            for (size_t k = 0; k < n; k++) {
                FUZZ_ASSERT(arr[k] == arr[k]);
            }
        }
        hd_toml_entry_error(&doc, e, e2, sizeof e2, "fuzz");
        FUZZ_ASSERT(strchr(e2, '\n') == NULL);
    }
    for (size_t i = 0; i < doc.n_aot; i++) {
        FUZZ_ASSERT(hd_toml_table_count(&doc, doc.aot_name[i]) == doc.aot_count[i]);
    }
    FUZZ_ASSERT(hd_toml_first_unused(&doc, "") == NULL);
    hd_toml_free(&doc);
    return 0;
}
