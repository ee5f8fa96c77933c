/* The RAW path's control step in integers, as the board runs it at 400 Hz after the filter: the angles read
 * from ikf_q's quaternion (libfixmath's fix16_atan2 with the report's piecewise-linear correction, section 3.10,
 * as fcb_sim/estimation/fixed.py, its products saturating), the cascaded P controllers of fcb_sim/board/control.py with Q16.16 gains, and the
 * mixing with the appendix's integer square root (control.isqrt_nr). C99, no dynamic memory, no floating point.
 * Measured on the Cortex-M0 by bench.profile (fcb_sim/hosts/m0emu.py); docs/board.md, "Cycles from execution".
 */
#ifndef CTL_Q_H
#define CTL_Q_H

#include <stdint.h>

typedef struct {
    int32_t p1, p2, yaw_p; /* Q16.16 */
} ctlq_gains_t;

typedef struct {
    int32_t q[4];                   /* the filter's attitude, Q2.30 (ikfq_predicted) */
    int32_t sp, sq, sr;             /* calibrated body rates, gyro LSB (FRD) */
    int32_t roll, pitch, yaw, lift; /* sticks with trims: int16, lift 0..32767 */
} ctlq_in_t;

/* fix16_atan2 (libfixmath) plus the report's correction: Q16.16 in, Q16.16 radians out. */
int32_t ctlq_atan2(int32_t y, int32_t x);
/* phi (roll) and theta (minus the z-up pitch), Q16.16 rad, from a Q2.30 quaternion (body to earth, z up). */
void ctlq_angles(const int32_t q[4], int32_t *phi, int32_t *theta);
/* The same from the quaternion's top 16 bits (fcb_sim/estimation/ikf_lite.py, angles_lite): an atan2 from one
 * 32-bit division and a 7th-order polynomial (0.011 deg at most), the pitch's cosine by a 32-bit root. */
int32_t ctlq_atan2_q15(int32_t y, int32_t x); /* any common scale in, Q15 radians out */
void ctlq_angles_lite(const int32_t q[4], int32_t *phi, int32_t *theta);
/* control.mix: lift Z (negative up) and moments L, M, N in ae^2 to ae1..ae4, at least idle while armed. */
void ctlq_mix(int32_t z, int32_t l, int32_t m, int32_t n, int32_t idle, int16_t ae[4]);
/* The control law alone (what Figure 14's control row holds): cascade, yaw rate, lift, mixing, on the angles
 * phi and theta (Q16.16 rad) the filter task read. */
void ctlq_law(const ctlq_gains_t *g, const ctlq_in_t *in, int32_t phi, int32_t theta, int16_t ae[4]);
/* One RAW control step: the angles from in->q, then the law. */
void ctlq_step(const ctlq_gains_t *g, const ctlq_in_t *in, int16_t ae[4]);

#endif
