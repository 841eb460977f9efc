/*
 * hd_co_types.h - object dictionary entry layout shared by the generated
 * table (hd_co_od.c) and the CANopen services (hd_co_od_access.c and the others, hd_co.h).
 *
 * An entry is {index, sub, type, access, flags, kind, arg, min, max, def, str}.
 * The table is const and sorted by (index, sub); the data it describes lives
 * in the device struct (hd_co_t.od, type hd_co_od_data_t), so the table holds
 * OFFSETS into that struct, never pointers: many devices can share one table.
 *   kind VAR      arg = byte offset of the value in hd_co_od_data_t
 *   kind PARAM    arg = drive parameter id (hd_param_id_t), value kept by the app
 *   kind DOMAIN   arg = domain id, data streamed through the app callbacks
 *   kind STR      str = constant visible string
 *   kind SPECIAL  value computed / acted on by the stack (0x1003, 0x1010, ...)
 */
#ifndef HD_CO_TYPES_H
#define HD_CO_TYPES_H

#include <stdint.h>

/* CANopen data type codes (CiA 301 table 44). */
#define HD_CO_T_BOOL    0x01u
#define HD_CO_T_I8      0x02u
#define HD_CO_T_I16     0x03u
#define HD_CO_T_I32     0x04u
#define HD_CO_T_U8      0x05u
#define HD_CO_T_U16     0x06u
#define HD_CO_T_U32     0x07u
#define HD_CO_T_VSTR    0x09u
#define HD_CO_T_DOMAIN  0x0Fu
#define HD_CO_T_I64     0x15u
#define HD_CO_T_U64     0x1Bu

/* Access bits. */
#define HD_CO_A_R      0x01u
#define HD_CO_A_W      0x02u
#define HD_CO_A_RO     HD_CO_A_R
#define HD_CO_A_WO     HD_CO_A_W
#define HD_CO_A_RW     (HD_CO_A_R | HD_CO_A_W)
#define HD_CO_A_CONST  (HD_CO_A_R | 0x04u)

/* Flags. */
#define HD_CO_F_TPDO    0x01u  /* may be mapped into a TPDO */
#define HD_CO_F_RPDO    0x02u  /* may be mapped into an RPDO */
#define HD_CO_F_STORE   0x04u  /* part of the stored communication parameters */
#define HD_CO_F_COS     0x08u  /* a change triggers event-driven TPDOs (type 254/255) */
#define HD_CO_F_NODEID  0x10u  /* default is relative to the node id */

/* Storage kinds. */
#define HD_CO_K_VAR      0u
#define HD_CO_K_PARAM    1u
#define HD_CO_K_DOMAIN   2u
#define HD_CO_K_STR      3u
#define HD_CO_K_SPECIAL  4u

typedef struct {
    uint16_t index;
    uint8_t  sub;
    uint8_t  type;    /* HD_CO_T_* */
    uint8_t  access;  /* HD_CO_A_* */
    uint8_t  flags;   /* HD_CO_F_* */
    uint8_t  kind;    /* HD_CO_K_* */
    uint16_t arg;     /* offset / param id / domain id */
    int64_t  min, max, def;  /* write limits and default (u64: checked up to INT64_MAX) */
    const char *str;  /* HD_CO_K_STR value */
} hd_co_entry_t;

#endif /* HD_CO_TYPES_H */
