/*
 * insncount.c - QEMU TCG plugin (plugin API v1, QEMU 7.2) that counts
 * executed guest instructions and logs the running count each time the
 * instruction at address `mark` is executed.
 *
 *   qemu-system-arm ... -plugin build/tools/libinsncount.so,mark=0xADDR,out=FILE
 *
 * Output (FILE, default stderr): one "MARK <count>" line per execution of
 * the mark address (count = instructions executed before it), then
 * "INSNS <total>" at exit.
 *
 * Profile of one window: with window=K,pcs=PCFILE it also writes, when the
 * mark executes for the (K+2)-th time, one "PC <addr> <count>" line per guest
 * instruction executed between the (K+1)-th and the (K+2)-th execution of the
 * mark (K counts from 0, as the MARK lines: the window of MARK lines K and
 * K+1); the counts add up to the difference of those two MARK counts.  Every
 * translated instruction gets its own counter (an inline add, as the total);
 * a mark snapshots them, so the profile costs the emulation nothing between
 * the marks.  A retranslated instruction has several counters: the reader
 * adds the lines of one address.  Debian ships no qemu-plugin.h, so the few
 * prototypes of the stable plugin ABI are declared here by hand.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stdbool.h>
#include <stddef.h>

#define QEMU_PLUGIN_EXPORT __attribute__((visibility("default")))

typedef uint64_t qemu_plugin_id_t;
struct qemu_plugin_tb;
struct qemu_plugin_insn;
typedef struct qemu_info_t qemu_info_t;
enum qemu_plugin_cb_flags { QEMU_PLUGIN_CB_NO_REGS = 0 };
enum qemu_plugin_op { QEMU_PLUGIN_INLINE_ADD_U64 = 0 };
typedef void (*qemu_plugin_vcpu_tb_trans_cb_t)(qemu_plugin_id_t id, struct qemu_plugin_tb *tb);
typedef void (*qemu_plugin_vcpu_udata_cb_t)(unsigned int vcpu_index, void *userdata);
typedef void (*qemu_plugin_udata_cb_t)(qemu_plugin_id_t id, void *userdata);

void qemu_plugin_register_vcpu_tb_trans_cb(qemu_plugin_id_t id, qemu_plugin_vcpu_tb_trans_cb_t cb);
void qemu_plugin_register_atexit_cb(qemu_plugin_id_t id, qemu_plugin_udata_cb_t cb, void *userdata);
size_t qemu_plugin_tb_n_insns(const struct qemu_plugin_tb *tb);
struct qemu_plugin_insn *qemu_plugin_tb_get_insn(const struct qemu_plugin_tb *tb, size_t idx);
uint64_t qemu_plugin_insn_vaddr(const struct qemu_plugin_insn *insn);
void qemu_plugin_register_vcpu_insn_exec_inline(struct qemu_plugin_insn *insn, enum qemu_plugin_op op,
                                                void *ptr, uint64_t imm);
void qemu_plugin_register_vcpu_insn_exec_cb(struct qemu_plugin_insn *insn, qemu_plugin_vcpu_udata_cb_t cb,
                                            enum qemu_plugin_cb_flags flags, void *userdata);

QEMU_PLUGIN_EXPORT int qemu_plugin_version = 1;
QEMU_PLUGIN_EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                           int argc, char **argv);

static uint64_t insn_count;     /* single vCPU (Cortex-M) */
static uint64_t mark_addr = UINT64_MAX;
static FILE *out;

/* profile of one window (window=K, pcs=FILE) */
typedef struct {
    uint64_t vaddr;
    uint64_t count;
    uint64_t at_start;          /* count when the window opened */
} pc_counter_t;
static pc_counter_t **ctrs;     /* one per translated instruction, never freed (the image is small) */
static size_t n_ctrs, cap_ctrs;
static long long window = -1;
static unsigned long long marks_seen;
static FILE *pcs;

static pc_counter_t *new_counter(uint64_t vaddr)
{
    if (n_ctrs == cap_ctrs) {
        size_t cap = cap_ctrs ? 2u * cap_ctrs : 4096u;
        pc_counter_t **p = realloc(ctrs, cap * sizeof *p);
        if (p == NULL) {
            return NULL;
        }
        ctrs = p;
        cap_ctrs = cap;
    }
    pc_counter_t *c = calloc(1, sizeof *c);
    if (c != NULL) {
        c->vaddr = vaddr;
        ctrs[n_ctrs++] = c;
    }
    return c;
}

static void on_mark(unsigned int vcpu_index, void *userdata)
{
    size_t i;
    (void)vcpu_index;
    (void)userdata;
    fprintf(out, "MARK %llu\n", (unsigned long long)insn_count);
    if (pcs != NULL && window >= 0) {
        if (marks_seen == (unsigned long long)window) {
            for (i = 0; i < n_ctrs; i++) {
                ctrs[i]->at_start = ctrs[i]->count;
            }
        } else if (marks_seen == (unsigned long long)window + 1u) {
            for (i = 0; i < n_ctrs; i++) {
                if (ctrs[i]->count > ctrs[i]->at_start) {
                    fprintf(pcs, "PC 0x%llx %llu\n", (unsigned long long)ctrs[i]->vaddr,
                            (unsigned long long)(ctrs[i]->count - ctrs[i]->at_start));
                }
            }
            fclose(pcs);
            pcs = NULL;
        }
    }
    marks_seen++;
}

static void on_tb_trans(qemu_plugin_id_t id, struct qemu_plugin_tb *tb)
{
    size_t i, n = qemu_plugin_tb_n_insns(tb);
    (void)id;
    for (i = 0; i < n; i++) {
        struct qemu_plugin_insn *insn = qemu_plugin_tb_get_insn(tb, i);
        /* the callback runs before this instruction's own increment is seen */
        if (qemu_plugin_insn_vaddr(insn) == mark_addr) {
            qemu_plugin_register_vcpu_insn_exec_cb(insn, on_mark, QEMU_PLUGIN_CB_NO_REGS, NULL);
        }
        qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &insn_count, 1);
        if (pcs != NULL) {
            /* a counter created after the window opened starts at 0: at_start 0 is right */
            pc_counter_t *c = new_counter(qemu_plugin_insn_vaddr(insn));
            if (c != NULL) {
                qemu_plugin_register_vcpu_insn_exec_inline(insn, QEMU_PLUGIN_INLINE_ADD_U64, &c->count, 1);
            }
        }
    }
}

static void on_plugin_exit(qemu_plugin_id_t id, void *userdata)
{
    (void)id;
    (void)userdata;
    fprintf(out, "INSNS %llu\n", (unsigned long long)insn_count);
    fflush(out);
    if (pcs != NULL) {          /* the window never closed: an empty profile, the reader refuses it */
        fclose(pcs);
        pcs = NULL;
    }
    if (out != stderr) {
        fclose(out);
    }
}

QEMU_PLUGIN_EXPORT int qemu_plugin_install(qemu_plugin_id_t id, const qemu_info_t *info,
                                           int argc, char **argv)
{
    int i;
    (void)info;
    out = stderr;
    for (i = 0; i < argc; i++) {
        if (strncmp(argv[i], "mark=", 5) == 0) {
            mark_addr = strtoull(argv[i] + 5, NULL, 0) & ~(uint64_t)1;   /* drop the Thumb bit */
        } else if (strncmp(argv[i], "out=", 4) == 0) {
            out = fopen(argv[i] + 4, "w");
            if (out == NULL) {
                fprintf(stderr, "insncount: cannot open %s\n", argv[i] + 4);
                return -1;
            }
        } else if (strncmp(argv[i], "window=", 7) == 0) {
            window = strtoll(argv[i] + 7, NULL, 0);
        } else if (strncmp(argv[i], "pcs=", 4) == 0) {
            pcs = fopen(argv[i] + 4, "w");
            if (pcs == NULL) {
                fprintf(stderr, "insncount: cannot open %s\n", argv[i] + 4);
                return -1;
            }
        } else {
            fprintf(stderr, "insncount: unknown argument '%s' (expected mark=ADDR, out=FILE, window=K, pcs=FILE)\n",
                    argv[i]);
            return -1;
        }
    }
    qemu_plugin_register_vcpu_tb_trans_cb(id, on_tb_trans);
    qemu_plugin_register_atexit_cb(id, on_plugin_exit, NULL);
    return 0;
}
