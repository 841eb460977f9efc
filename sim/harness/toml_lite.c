/*
 * toml_lite.c - strict reader for the TOML subset of toml_lite.h.
 *
 * Written to be fuzzed: every read is bounds-checked against the input length,
 * every copy against its destination, every allocation checked; no recursion.
 */
#include "toml_lite.h"
#include "sim_err.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *s;
    size_t len, pos;
    int32_t line, col;
    const char *fname;
    char *err;
    size_t errlen;
    hd_toml_doc_t *doc;
    char table[HD_TOML_MAX_KEY + 1];
} parser_t;


static int peekc(const parser_t *p)
{
    return p->pos < p->len ? (unsigned char)p->s[p->pos] : -1;
}

static int peekc_at(const parser_t *p, size_t k)
{
    return (p->pos + k < p->len) ? (unsigned char)p->s[p->pos + k] : -1;
}

static void adv(parser_t *p)
{
    if (p->pos >= p->len) return;
    if (p->s[p->pos] == '\n') {
        if (p->line < INT32_MAX) p->line++;
        p->col = 1;
    } else if (p->col < INT32_MAX) {
        p->col++;
    }
    p->pos++;
}

/* Description of the character at the cursor, for "found ..." */
static const char *found_desc(const parser_t *p, char *buf, size_t n)
{
    int c = peekc(p);
    if (c < 0) return "end of file";
    if (c == '\n' || (c == '\r' && peekc_at(p, 1) == '\n')) return "end of line";
    if (c >= 0x21 && c < 0x7f) {
        snprintf(buf, n, "'%c'", (char)c);
        return buf;
    }
    snprintf(buf, n, "byte 0x%02x", (unsigned)c);
    return buf;
}

static int perr(parser_t *p, const char *what)
{
    char b[16];
    sim_set_err(p->err, p->errlen, "%s:%ld:%ld: expected %s, found %s", p->fname,
            (long)p->line, (long)p->col, what, found_desc(p, b, sizeof b));
    return -1;
}

static int perr_at(parser_t *p, int32_t line, int32_t col, const char *msg)
{
    sim_set_err(p->err, p->errlen, "%s:%ld:%ld: %s", p->fname, (long)line, (long)col, msg);
    return -1;
}

static void skip_ws(parser_t *p)
{
    int c;
    while ((c = peekc(p)) == ' ' || c == '\t') adv(p);
}

/* comment: '#' up to end of line; control characters other than tab refused */
static int skip_comment(parser_t *p)
{
    if (peekc(p) != '#') return 0;
    for (;;) {
        int c = peekc(p);
        if (c < 0 || c == '\n') return 0;
        if (c == '\r' && peekc_at(p, 1) == '\n') return 0;
        if ((c < 0x20 && c != '\t') || c == 0x7f)
            return perr(p, "printable characters in the comment");
        adv(p);
    }
}

/* end of line (after optional spaces and comment) or end of file */
static int expect_eol(parser_t *p)
{
    skip_ws(p);
    if (skip_comment(p)) return -1;
    int c = peekc(p);
    if (c < 0) return 0;
    if (c == '\n') { adv(p); return 0; }
    if (c == '\r' && peekc_at(p, 1) == '\n') { adv(p); adv(p); return 0; }
    return perr(p, "end of line");
}

/* skip spaces, newlines and comments (inside arrays) */
static int skip_ws_nl(parser_t *p)
{
    for (;;) {
        skip_ws(p);
        if (skip_comment(p)) return -1;
        int c = peekc(p);
        if (c == '\n') { adv(p); continue; }
        if (c == '\r' && peekc_at(p, 1) == '\n') { adv(p); adv(p); continue; }
        return 0;
    }
}

static int is_bare(int c)
{
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
           c == '_' || c == '-';
}

static int append(char *dst, size_t cap, size_t *n, char c)
{
    if (*n + 1 >= cap) return -1;
    dst[(*n)++] = c;
    dst[*n] = '\0';
    return 0;
}

/* A quoted string ("basic" with escapes or 'literal') into out (cap bytes). */
static int parse_string(parser_t *p, char *out, size_t cap, size_t *outn)
{
    int q = peekc(p);
    size_t n = 0;
    out[0] = '\0';
    adv(p);
    for (;;) {
        int c = peekc(p);
        if (c < 0 || c == '\n' || c == '\r')
            return perr(p, q == '"' ? "closing '\"' of the string" : "closing ' of the string");
        if (c == q) { adv(p); break; }
        if ((c < 0x20 && c != '\t') || c == 0x7f)
            return perr(p, "printable characters in the string");
        if (q == '"' && c == '\\') {
            adv(p);
            int e = peekc(p);
            char r;
            switch (e) {
            case '"': r = '"'; break;
            case '\\': r = '\\'; break;
            case 'n': r = '\n'; break;
            case 't': r = '\t'; break;
            case 'r': r = '\r'; break;
            default: return perr(p, "an escape \\\" \\\\ \\n \\t or \\r");
            }
            if (append(out, cap, &n, r)) return perr(p, "a shorter string");
            adv(p);
            continue;
        }
        if (append(out, cap, &n, (char)c)) return perr(p, "a shorter string");
        adv(p);
    }
    if (outn) *outn = n;
    return 0;
}

/* key = part ('.' part)*, appended to buf (which may already hold a prefix) */
static int parse_key(parser_t *p, char *buf, size_t cap, size_t *n)
{
    for (;;) {
        skip_ws(p);
        int c = peekc(p);
        if (*n > 0 && append(buf, cap, n, '.')) return perr(p, "a shorter key");
        if (c == '"' || c == '\'') {
            char part[HD_TOML_MAX_KEY + 1];
            size_t pn = 0;
            if (parse_string(p, part, sizeof part, &pn)) return -1;
            if (pn == 0) return perr(p, "a non-empty key");
            for (size_t i = 0; i < pn; i++) {
                if (part[i] == '.' || (unsigned char)part[i] < 0x20)
                    return perr(p, "a quoted key without '.' or control characters");
                if (append(buf, cap, n, part[i])) return perr(p, "a shorter key");
            }
        } else if (is_bare(c)) {
            while (is_bare(peekc(p))) {
                if (append(buf, cap, n, (char)peekc(p))) return perr(p, "a shorter key");
                adv(p);
            }
        } else {
            return perr(p, "a key (letters, digits, '_', '-' or a quoted name)");
        }
        skip_ws(p);
        if (peekc(p) != '.') return 0;
        adv(p);
    }
}

/* ---- numbers ------------------------------------------------------------------ */

static int is_digit(int c) { return c >= '0' && c <= '9'; }

/* digits with single '_' between digits; copies digits into buf */
static int scan_digits(parser_t *p, char *buf, size_t cap, size_t *n)
{
    if (!is_digit(peekc(p))) return perr(p, "a digit");
    for (;;) {
        if (append(buf, cap, n, (char)peekc(p))) return perr(p, "a shorter number");
        adv(p);
        int c = peekc(p);
        if (c == '_') {
            adv(p);
            if (!is_digit(peekc(p))) return perr(p, "a digit after '_'");
            continue;
        }
        if (!is_digit(c)) return 0;
    }
}

static int parse_number(parser_t *p, double *out, int *is_int)
{
    char buf[128];
    size_t n = 0;
    int32_t l0 = p->line, c0 = p->col;
    buf[0] = '\0';
    int c = peekc(p);
    if (c == '+' || c == '-') {
        if (c == '-') append(buf, sizeof buf, &n, '-');
        adv(p);
        c = peekc(p);
    }
    if (c == 'i' || c == 'n') {
        int isinf = (c == 'i');
        const char *w = isinf ? "inf" : "nan";
        for (size_t i = 0; i < 3; i++) {
            if (peekc(p) != w[i]) return perr(p, "a number");
            adv(p);
        }
        if (!isinf) return perr_at(p, l0, c0, "expected a finite number, found nan");
        *out = (n > 0) ? -HUGE_VAL : HUGE_VAL;
        *is_int = 0;
        goto delim;
    }
    if (!is_digit(c)) return perr(p, "a value (number, \"string\", true/false or [array])");
    {
        size_t int_start = n;
        if (scan_digits(p, buf, sizeof buf, &n)) return -1;
        if (n - int_start > 1 && buf[int_start] == '0')
            return perr_at(p, l0, c0, "expected a number without leading zeros");
    }
    *is_int = 1;
    if (peekc(p) == '.') {
        append(buf, sizeof buf, &n, '.');
        adv(p);
        if (scan_digits(p, buf, sizeof buf, &n)) return -1;
        *is_int = 0;
    }
    if (peekc(p) == 'e' || peekc(p) == 'E') {
        append(buf, sizeof buf, &n, 'e');
        adv(p);
        c = peekc(p);
        if (c == '+' || c == '-') {
            if (append(buf, sizeof buf, &n, (char)c)) return perr(p, "a shorter number");
            adv(p);
        }
        if (scan_digits(p, buf, sizeof buf, &n)) return -1;
        *is_int = 0;
    }
    errno = 0;
    {
        char *end = NULL;
        double v = strtod(buf, &end);
        if (end == buf || *end != '\0' || !isfinite(v))
            return perr_at(p, l0, c0, "expected a number within the double range");
        *out = v;
    }
delim:
    c = peekc(p);
    if (c < 0 || c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == ',' || c == ']' || c == '#')
        return 0;
    return perr(p, "end of the number");
}

/* ---- document building ---------------------------------------------------------- */

static char *dupstr(const char *s)
{
    size_t n = strlen(s);
    char *d = malloc(n + 1);
    if (d) memcpy(d, s, n + 1);
    return d;
}

static void free_entry(hd_toml_entry_t *e)
{
    free(e->key);
    free(e->str);
    free(e->arr);
    if (e->sarr) {
        for (size_t i = 0; i < e->n; i++) free(e->sarr[i]);
        free(e->sarr);
    }
    memset(e, 0, sizeof *e);
}

void hd_toml_free(hd_toml_doc_t *doc)
{
    if (!doc) return;
    for (size_t i = 0; i < doc->n; i++) free_entry(&doc->e[i]);
    free(doc->e);
    for (size_t i = 0; i < doc->n_aot; i++) free(doc->aot_name[i]);
    free(doc->aot_name);
    free(doc->aot_count);
    free(doc->file);
    memset(doc, 0, sizeof *doc);
}

/* 1 if a is b or a prefix of b at a '.' boundary (or the other way) */
static int key_conflict(const char *a, const char *b)
{
    size_t la = strlen(a), lb = strlen(b);
    size_t m = la < lb ? la : lb;
    if (strncmp(a, b, m) != 0) return 0;
    if (la == lb) return 1;
    return (la < lb) ? (b[la] == '.') : (a[lb] == '.');
}

static int add_entry(parser_t *p, hd_toml_entry_t *e, const char *key)
{
    hd_toml_doc_t *d = p->doc;
    for (size_t i = 0; i < d->n; i++) {
        if (key_conflict(d->e[i].key, key)) {
            char msg[HD_TOML_MAX_KEY * 2 + 96];
            snprintf(msg, sizeof msg, "key '%s' is already defined (line %ld)", key,
                     (long)d->e[i].line);
            return perr_at(p, e->line, e->col, msg);
        }
    }
    if (d->n >= HD_TOML_MAX_ENTRIES)
        return perr_at(p, e->line, e->col, "too many keys (limit reached)");
    if (d->n == d->cap) {
        size_t nc = d->cap ? d->cap * 2 : 32;
        hd_toml_entry_t *ne = realloc(d->e, nc * sizeof *ne);
        if (!ne) return perr_at(p, e->line, e->col, "out of memory");
        d->e = ne;
        d->cap = nc;
    }
    e->key = dupstr(key);
    if (!e->key) return perr_at(p, e->line, e->col, "out of memory");
    d->e[d->n++] = *e;
    return 0;
}

static int parse_array(parser_t *p, hd_toml_entry_t *e)
{
    size_t cap = 0;
    adv(p); /* '[' */
    e->type = HD_TOML_NUM_ARRAY;
    e->n = 0;
    int kind = 0; /* 0 unknown, 1 numbers, 2 strings */
    for (;;) {
        if (skip_ws_nl(p)) return -1;
        int c = peekc(p);
        if (c == ']') { adv(p); break; }
        if (e->n >= HD_TOML_MAX_ARRAY) return perr(p, "a shorter array");
        int this_kind = (c == '"' || c == '\'') ? 2 : 1;
        if (c == '[') return perr(p, "a number or a string (nested arrays are not supported)");
        if (kind && kind != this_kind)
            return perr(p, kind == 1 ? "a number (arrays hold one type)" : "a string (arrays hold one type)");
        kind = this_kind;
        if (e->n == cap) {
            size_t nc = cap ? cap * 2 : 8;
            if (kind == 1) {
                double *na = realloc(e->arr, nc * sizeof *na);
                if (!na) return perr(p, "a smaller array (out of memory)");
                e->arr = na;
            } else {
                char **na = realloc(e->sarr, nc * sizeof *na);
                if (!na) return perr(p, "a smaller array (out of memory)");
                e->sarr = na;
            }
            cap = nc;
        }
        if (kind == 1) {
            int isint;
            if (parse_number(p, &e->arr[e->n], &isint)) return -1;
            e->n++;
        } else {
            char buf[HD_TOML_MAX_STR + 1];
            size_t sn;
            if (parse_string(p, buf, sizeof buf, &sn)) return -1;
            char *s = dupstr(buf);
            if (!s) return perr(p, "a smaller array (out of memory)");
            e->sarr[e->n++] = s;
        }
        if (skip_ws_nl(p)) return -1;
        c = peekc(p);
        if (c == ',') { adv(p); continue; }
        if (c == ']') { adv(p); break; }
        return perr(p, "',' or ']' in the array");
    }
    if (kind == 2) e->type = HD_TOML_STR_ARRAY;
    return 0;
}

static int parse_value(parser_t *p, hd_toml_entry_t *e)
{
    int c = peekc(p);
    e->line = p->line;
    e->col = p->col;
    if (c == '"' || c == '\'') {
        char buf[HD_TOML_MAX_STR + 1];
        size_t n;
        if (peekc_at(p, 1) == c && peekc_at(p, 2) == c)
            return perr(p, "a one-line string (multi-line strings are not supported)");
        if (parse_string(p, buf, sizeof buf, &n)) return -1;
        e->type = HD_TOML_STRING;
        e->str = dupstr(buf);
        if (!e->str) return perr(p, "a shorter string (out of memory)");
        return 0;
    }
    if (c == 't' || c == 'f') {
        const char *w = (c == 't') ? "true" : "false";
        size_t wl = strlen(w);
        for (size_t i = 0; i < wl; i++) {
            if (peekc(p) != w[i]) return perr(p, "true or false");
            adv(p);
        }
        if (is_bare(peekc(p))) return perr(p, "end of the value");
        e->type = HD_TOML_BOOL;
        e->boolean = (c == 't');
        return 0;
    }
    if (c == '[') return parse_array(p, e);
    if (c == '{') return perr(p, "a value (inline tables are not supported)");
    e->type = HD_TOML_NUMBER;
    return parse_number(p, &e->num, &e->is_integer);
}

static int aot_next(parser_t *p, const char *name, size_t *index)
{
    hd_toml_doc_t *d = p->doc;
    for (size_t i = 0; i < d->n_aot; i++) {
        if (strcmp(d->aot_name[i], name) == 0) {
            if (d->aot_count[i] >= HD_TOML_MAX_TABLES) return perr(p, "fewer tables (limit reached)");
            *index = d->aot_count[i]++;
            return 0;
        }
    }
    if (d->n_aot >= HD_TOML_MAX_TABLES) return perr(p, "fewer table names (limit reached)");
    if (d->n_aot == d->cap_aot) {
        size_t nc = d->cap_aot ? d->cap_aot * 2 : 4;
        char **nn = realloc(d->aot_name, nc * sizeof *nn);
        if (!nn) return perr(p, "less (out of memory)");
        d->aot_name = nn;
        size_t *ncount = realloc(d->aot_count, nc * sizeof *ncount);
        if (!ncount) return perr(p, "less (out of memory)");
        d->aot_count = ncount;
        d->cap_aot = nc;
    }
    d->aot_name[d->n_aot] = dupstr(name);
    if (!d->aot_name[d->n_aot]) return perr(p, "less (out of memory)");
    d->aot_count[d->n_aot] = 1;
    d->n_aot++;
    *index = 0;
    return 0;
}

static int parse_header(parser_t *p)
{
    int aot = 0;
    adv(p); /* '[' */
    if (peekc(p) == '[') { adv(p); aot = 1; }
    char name[HD_TOML_MAX_KEY + 1];
    size_t n = 0;
    name[0] = '\0';
    if (parse_key(p, name, sizeof name, &n)) return -1;
    if (peekc(p) != ']') return perr(p, aot ? "']]'" : "']'");
    adv(p);
    if (aot) {
        if (peekc(p) != ']') return perr(p, "']]'");
        adv(p);
        size_t idx = 0;
        if (aot_next(p, name, &idx)) return -1;
        int w = snprintf(p->table, sizeof p->table, "%s.%zu", name, idx);
        if (w < 0 || (size_t)w >= sizeof p->table) return perr(p, "a shorter table name");
    } else {
        memcpy(p->table, name, n + 1);
    }
    return expect_eol(p);
}

static int parse_keyval(parser_t *p)
{
    char key[HD_TOML_MAX_KEY + 1];
    size_t n = strlen(p->table);
    memcpy(key, p->table, n + 1);
    int32_t kl = p->line, kc = p->col;
    if (parse_key(p, key, sizeof key, &n)) return -1;
    if (peekc(p) != '=') return perr(p, "'=' after the key");
    adv(p);
    skip_ws(p);
    hd_toml_entry_t e;
    memset(&e, 0, sizeof e);
    if (parse_value(p, &e)) { free_entry(&e); return -1; }
    int32_t vl = e.line, vc = e.col;
    e.line = kl;
    e.col = kc;
    if (add_entry(p, &e, key)) { free_entry(&e); return -1; }
    p->doc->e[p->doc->n - 1].line = vl;
    p->doc->e[p->doc->n - 1].col = vc;
    return expect_eol(p);
}

int hd_toml_parse(const char *text, size_t len, const char *fname,
                  hd_toml_doc_t *doc, char *err, size_t errlen)
{
    parser_t p;
    memset(doc, 0, sizeof *doc);
    memset(&p, 0, sizeof p);
    p.s = text;
    p.len = len;
    p.line = 1;
    p.col = 1;
    p.fname = fname ? fname : "<toml>";
    p.err = err;
    p.errlen = errlen;
    p.doc = doc;
    if (err && errlen) err[0] = '\0';
    if (len > HD_TOML_MAX_FILE) {
        sim_set_err(err, errlen, "%s: file too large (more than %u bytes)", p.fname, HD_TOML_MAX_FILE);
        return -1;
    }
    doc->file = dupstr(p.fname);
    if (!doc->file) { sim_set_err(err, errlen, "%s: out of memory", p.fname); return -1; }
    /* UTF-8 BOM */
    if (len >= 3 && (unsigned char)text[0] == 0xef && (unsigned char)text[1] == 0xbb &&
        (unsigned char)text[2] == 0xbf)
        p.pos = 3;
    while (p.pos < p.len) {
        skip_ws(&p);
        int c = peekc(&p);
        int rc = 0;
        if (c < 0) break;
        if (c == '#' || c == '\n' || c == '\r') rc = expect_eol(&p);
        else if (c == '[') rc = parse_header(&p);
        else rc = parse_keyval(&p);
        if (rc) { hd_toml_free(doc); return -1; }
    }
    return 0;
}

int hd_toml_load(const char *path, hd_toml_doc_t *doc, char *err, size_t errlen)
{
    memset(doc, 0, sizeof *doc);
    FILE *f = fopen(path, "rb");
    if (!f) {
        sim_set_err(err, errlen, "%s: cannot read: %s", path, strerror(errno));
        return -1;
    }
    size_t cap = 4096, n = 0;
    char *buf = malloc(cap);
    if (!buf) { fclose(f); sim_set_err(err, errlen, "%s: out of memory", path); return -1; }
    for (;;) {
        if (n == cap) {
            if (cap > HD_TOML_MAX_FILE) {
                free(buf); fclose(f);
                sim_set_err(err, errlen, "%s: file too large (more than %u bytes)", path, HD_TOML_MAX_FILE);
                return -1;
            }
            char *nb = realloc(buf, cap * 2);
            if (!nb) { free(buf); fclose(f); sim_set_err(err, errlen, "%s: out of memory", path); return -1; }
            buf = nb;
            cap *= 2;
        }
        size_t r = fread(buf + n, 1, cap - n, f);
        n += r;
        if (r == 0) break;
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) { free(buf); sim_set_err(err, errlen, "%s: read error", path); return -1; }
    int rc = hd_toml_parse(buf, n, path, doc, err, errlen);
    free(buf);
    return rc;
}

hd_toml_entry_t *hd_toml_find(hd_toml_doc_t *doc, const char *key)
{
    for (size_t i = 0; i < doc->n; i++) {
        if (strcmp(doc->e[i].key, key) == 0) {
            doc->e[i].used = 1;
            return &doc->e[i];
        }
    }
    return NULL;
}

size_t hd_toml_table_count(const hd_toml_doc_t *doc, const char *name)
{
    for (size_t i = 0; i < doc->n_aot; i++)
        if (strcmp(doc->aot_name[i], name) == 0) return doc->aot_count[i];
    return 0;
}

static const char *type_name(hd_toml_type_t t)
{
    switch (t) {
    case HD_TOML_NUMBER: return "a number";
    case HD_TOML_STRING: return "a string";
    case HD_TOML_BOOL: return "true/false";
    case HD_TOML_NUM_ARRAY: return "an array of numbers";
    case HD_TOML_STR_ARRAY: return "an array of strings";
    }
    return "a value";
}

void hd_toml_entry_error(const hd_toml_doc_t *doc, const hd_toml_entry_t *e,
                         char *err, size_t errlen, const char *msg)
{
    sim_set_err(err, errlen, "%s:%ld:%ld: %s: %s", doc->file ? doc->file : "<toml>",
            (long)e->line, (long)e->col, e->key, msg);
}

static int typed(hd_toml_doc_t *doc, const char *key, hd_toml_type_t t,
                 hd_toml_entry_t **out, char *err, size_t errlen)
{
    hd_toml_entry_t *e = hd_toml_find(doc, key);
    if (!e) return 0;
    if (e->type != t) {
        char msg[96];
        snprintf(msg, sizeof msg, "expected %s, found %s", type_name(t), type_name(e->type));
        hd_toml_entry_error(doc, e, err, errlen, msg);
        return -1;
    }
    *out = e;
    return 1;
}

int hd_toml_get_number(hd_toml_doc_t *doc, const char *key, double *out, char *err, size_t errlen)
{
    hd_toml_entry_t *e = NULL;
    int rc = typed(doc, key, HD_TOML_NUMBER, &e, err, errlen);
    if (rc == 1) *out = e->num;
    return rc;
}

int hd_toml_get_string(hd_toml_doc_t *doc, const char *key, const char **out, char *err, size_t errlen)
{
    hd_toml_entry_t *e = NULL;
    int rc = typed(doc, key, HD_TOML_STRING, &e, err, errlen);
    if (rc == 1) *out = e->str;
    return rc;
}

int hd_toml_get_bool(hd_toml_doc_t *doc, const char *key, int *out, char *err, size_t errlen)
{
    hd_toml_entry_t *e = NULL;
    int rc = typed(doc, key, HD_TOML_BOOL, &e, err, errlen);
    if (rc == 1) *out = e->boolean;
    return rc;
}

int hd_toml_get_num_array(hd_toml_doc_t *doc, const char *key, const double **out, size_t *n,
                          char *err, size_t errlen)
{
    hd_toml_entry_t *e = hd_toml_find(doc, key);
    if (!e) return 0;
    if (e->type == HD_TOML_NUM_ARRAY) {
        *out = e->arr;
        *n = e->n;
        return 1;
    }
    hd_toml_entry_error(doc, e, err, errlen, "expected an array of numbers");
    return -1;
}

const hd_toml_entry_t *hd_toml_first_unused(const hd_toml_doc_t *doc, const char *prefix)
{
    size_t pl = prefix ? strlen(prefix) : 0;
    for (size_t i = 0; i < doc->n; i++)
        if (!doc->e[i].used && (pl == 0 || strncmp(doc->e[i].key, prefix, pl) == 0))
            return &doc->e[i];
    return NULL;
}
