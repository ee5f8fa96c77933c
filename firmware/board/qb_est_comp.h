/* qb_est_comp.h: the lab report's two complementary estimators, the ones its preset flies (est.attitude
 * complementary, est.height complementary): fcb_sim/estimation/complementary.py (eq. 1, in qb_real as
 * ComplementaryFilter and in Q16.16 as ComplementaryFilterQ16, libfixmath's semantics with the report's corrected
 * atan2) and fcb_sim/estimation/height.py's HeightEstimator (Figure 10) as make_height_estimator("complementary")
 * builds it. Included by qb_board.h (qb_real); the constants are generated into qb_estimator.h.
 *
 * QB_REPORT_EST: 1 builds them (the host boards); the Cortex-M0 image leaves them out for flash (its 40 KB budget,
 * issue 37), and its board answers NOT_IMPLEMENTED to either value (docs/firmware.md). */
#ifndef QB_EST_COMP_H
#define QB_EST_COMP_H

#include <stdint.h>

#ifndef QB_REPORT_EST
#if defined(__ARM_ARCH_6M__) /* the Cortex-M0 image: no room in its flash budget */
#define QB_REPORT_EST 0
#else
#define QB_REPORT_EST 1
#endif
#endif

/* eq. 1 per axis; the float state or the Q16.16 one, by est.fixed_point (as param_bindings.build_filter). */
typedef struct {
    uint8_t fixed, started;
    qb_real k_gyro;           /* float: K_gyro (est.k_gyro) */
    qb_real roll, pitch, yaw; /* float: rad, z up */
    int32_t k_acc, r, p, y;   /* Q16.16: 1 - K_gyro, and the angles */
} qb_comp_t;

void qb_comp_init(qb_comp_t *f, qb_real k_gyro, int fixed);
void qb_comp_reset(qb_comp_t *f);
/* Gyro (rad/s) and specific force (m/s^2), chip frame z up, and the time step (s). */
void qb_comp_update(qb_comp_t *f, qb_real gx, qb_real gy, qb_real gz, qb_real ax, qb_real ay, qb_real az, qb_real dt);
/* Roll, pitch, yaw (rad, z up); and the body-to-earth quaternion of those angles (w x y z). */
void qb_comp_angles(const qb_comp_t *f, qb_real out[3]);
void qb_comp_quaternion(const qb_comp_t *f, qb_real q[4]);

/* Figure 10: a velocity and a position complementary filter between the high-passed earth-frame acceleration and
 * the low-passed barometer. No capture, no ground test, no hard stops: the report's estimator has none. */
typedef struct {
    qb_real p_ref, k_pa_per_m;
    qb_real height, vz, az_earth, baro_raw, baro_height, baro_vz;
    qb_real hp_b_in, hp_b_out, lp_v, hp_a_in, hp_a_out;
    uint8_t a_primed;
} qb_hcomp_t;

void qb_hcomp_reset(qb_hcomp_t *h, qb_real pressure_pa);
void qb_hcomp_update_imu(qb_hcomp_t *h, qb_real ax, qb_real ay, qb_real az, qb_real qw, qb_real qx, qb_real qy,
                         qb_real qz, qb_real dt);
void qb_hcomp_update_baro(qb_hcomp_t *h, qb_real pressure_pa, qb_real dt);

#endif /* QB_EST_COMP_H */
