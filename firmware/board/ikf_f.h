/* The RAW path's attitude filter ("ikf") in double precision: the C of fcb_sim/estimation/ikf.py, operation for
 * operation, so the same IEEE doubles come out (tests/estimation/test_ikf_native.py; built with -ffp-contract=off, no
 * fused multiply-adds). It is the simulator's hot path (fcb_sim.estimation.native), not board code: the board has no FPU
 * (docs/board.md, "Cycles from execution"). Same parameters as the Python class; q_g0 is (sqrt(2) / tau)^4.
 */
#ifndef IKF_F_H
#define IKF_F_H

typedef struct {
    double q_g0, k_rot, drift_init, drift_noise, latency, rest_r, rest_gyro, rest_acc, rest_time, rest_tau;
    double rest_bias_tau, bias_max;
} ikff_params_t;

typedef struct {
    ikff_params_t p;
    double w, x, y, z, vx, vy, dx, dy, pvv, pvg, pvd, pgg, pgd, pdd, bx, by, bz, rx, ry, rz;
    double gl[3], al[3], rest_t;
    int at_rest, started;
} ikff_t;

void ikff_init(ikff_t *s, const ikff_params_t *p);
void ikff_reset(ikff_t *s);
void ikff_update(ikff_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt);
/* The attitude predicted latency ahead along the current rate (w, x, y, z). */
void ikff_quaternion(const ikff_t *s, double q[4]);
/* ikff_update, then ikff_quaternion (one call a sample from Python). */
void ikff_update_q(ikff_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt,
                   double q[4]);
unsigned ikff_size(void);

#endif
