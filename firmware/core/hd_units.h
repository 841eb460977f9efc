/*
 * hd_units.h - the signal formats of the drive (DESIGN.md sections 2-3).
 *
 * One format per physical signal, shared by every controller.  The full table
 * with ranges, LSBs in SI units and the margin arguments is docs/fixed-point.md;
 * keep the two in step.
 *
 *  signal                     C type    format                        LSB (SI)               range
 *  -------------------------  --------  ----------------------------  ---------------------  --------------------
 *  angle (output or motor)    int64_t   Q32.32 turns                  2^-32 turn = 1.463e-9 rad (3.02e-4 arcsec)  +-2^31 turns
 *  angle within one turn      uint32_t  2^32 == 1 turn (wraps, meant)  as above               [0, 1) turn
 *  output velocity            int32_t   2^-32 turn/s                  1.463e-9 rad/s          +-0.5 turn/s = +-180 deg/s
 *  motor velocity             int32_t   2^-24 turn/s                  3.745e-7 rad/s          +-128 turn/s = +-7680 rpm
 *  output acceleration        int32_t   2^-24 turn/s^2                3.745e-7 rad/s^2        +-128 turn/s^2
 *  torque (motor or output)   int32_t   Q15.16 N.m                    1.526e-5 N.m            +-32768 N.m
 *  current                    int32_t   Q15.16 A                      1.526e-5 A              +-32768 A
 *  dimensionless gain/ratio   int32_t   Q30 unless stated             9.31e-10                [-2, 2)
 *  loop tick                  uint32_t  count of 100 us periods       1e-4 s                  wraps after 4.97 days (meant)
 *
 * Margins on the reference axis: 0.001 deg/s at the output is 11930 LSB of the
 * output-velocity format (0.008 % resolution); 60 deg/s is 7.16e8 LSB, 33 % of
 * the int32 range (3x margin).  0.0001 deg/s (slowest trajectory) is 1193 LSB.
 */
#ifndef HD_UNITS_H
#define HD_UNITS_H

#include <stdint.h>

#define HD_LOOP_HZ        10000
#define HD_ANGLE_FRAC_BITS   32   /* hd angle: Q32.32 turns */
#define HD_VEL_OUT_FRAC_BITS 32   /* output velocity: 2^-32 turn/s */
#define HD_VEL_MOT_FRAC_BITS 24   /* motor velocity: 2^-24 turn/s */
#define HD_ACC_FRAC_BITS     24   /* output acceleration: 2^-24 turn/s^2 */
#define HD_TORQUE_FRAC_BITS  16   /* torque: Q15.16 N.m */
#define HD_CURRENT_FRAC_BITS 16   /* current: Q15.16 A */

typedef int64_t  hd_angle_t;    /* Q32.32 turns */
typedef uint32_t hd_phase_t;    /* 2^32 == one turn, wraps */
typedef int32_t  hd_vel_out_t;  /* 2^-32 turn/s */
typedef int32_t  hd_vel_mot_t;  /* 2^-24 turn/s */
typedef int32_t  hd_acc_t;      /* 2^-24 turn/s^2 */
typedef int32_t  hd_torque_t;   /* Q15.16 N.m */
typedef int32_t  hd_current_t;  /* Q15.16 A */

#endif /* HD_UNITS_H */
