/* The RAW path's attitude filter ("ikf") in 32-bit fixed point: the C of fcb_sim/estimation/ikf_fixed.py,
 * bit-exact with it (tests/estimation/test_ikf_native.py feeds both the same BROAD samples and requires identical states), and
 * with ikfq_set_lite (or the table's lite) of ikf_lite.py, the variant cut to fit the Cortex-M0 that the default
 * board runs (tests/estimation/test_ikf_lite.py; docs/attitude.md, "The variant that fits the chip").
 *
 * C99, no dynamic memory, no floating point in the per-sample step (ikfq_step, ikfq_predicted): the board runs
 * those at 400 Hz. ikfq_init and ikfq_set_dt turn the float parameters into Q constants once (doubles, as the
 * Python twin computes them, so the constants are the same bits); the host wrapper ikfq_update takes floats
 * like the Python class. Formats (fractional bits) as ikf_fixed.Formats: samples and angles Q16.16, dt and the
 * quaternion Q2.30, bias and rest low-pass Q8.24, V and G_h Q8.24, D Q4.28, covariances and gains Q2.30.
 * Why each: docs/attitude.md, "Fixed point"; the cost on the Cortex-M0: docs/board.md.
 */
#ifndef IKF_Q_H
#define IKF_Q_H

#include <stdint.h>

typedef struct {
    uint8_t io, dt, quat, bias, vel, drift, cov; /* fractional bits of each group */
} ikfq_formats_t;

typedef struct {
    double q_g0;        /* (sqrt(2) / tau)^4 */
    double k_rot, drift_init, drift_noise, latency, rest_r, rest_gyro, rest_acc, rest_time, rest_tau;
    double rest_bias_tau, bias_max;
} ikfq_params_t;

typedef struct {
    ikfq_formats_t f;
    /* constants (ikfq_init) */
    int32_t qg_shift, q_g0, k_rot, drift_noise, rest_r, rest_g2, rest_a2, bias_max, inv_g0, lat_half;
    int32_t pgg0, pdd0, g0_io, swing_max, swing_k; /* the rebase's 0.81 one and 0.9 one */
    int64_t rest_time; /* Q.dt, not saturated to 32 bits */
    /* dt and what follows from it (ikfq_set_dt) */
    double dt_last, rest_tau_, rest_bias_tau_;
    int32_t dtq, dt2q, dthq, krq, kbq;
    /* state */
    int32_t qw, qx, qy, qz, vx, vy, dx, dy, pvv, pvg, pvd, pgg, pgd, pdd, bx, by, bz, rx, ry, rz;
    int32_t gl[3], al[3];
    int64_t rest_t; /* time at rest, Q.dt, held at rest_time */
    int32_t at_rest, started;
    int32_t from_table; /* set up by ikfq_init_q: dt is the table's, ikfq_set_dt leaves it */
    /* the gravity part (rest, Kalman, rebase) runs every decim-th sample, the strapdown every one (ikfq_set_decimation;
     * docs/attitude.md, "Decimation"): dtq, dt2q, krq and kbq are then of decim * dt, dthq of dt */
    int32_t decim, phase;
    /* the variant cut to fit the Cortex-M0 (ikfq_set_lite; fcb_sim/estimation/ikf_lite.py): its gravity part in
     * four pieces over the decim samples, and what passes between them (fsum: (0, the body-frame specific
     * force summed over the step's samples, Q.io), a quaternion; qm: q at their middle; also G_h, kept by the exact
     * one too) */
    int32_t lite, fsum[4], qm[4], rate, gxh, gyh;
} ikfq_t;

/* floor(sqrt(n)), bit by bit: exact, no division (the filter's turn rate, the control's cos(pitch)) */
uint32_t ikfq_isqrt32(uint32_t n);

/* The defaults of ikf_fixed.Formats and of ikf.InertialKalmanFilter's parameters. */
void ikfq_default_formats(ikfq_formats_t *f);
void ikfq_default_params(ikfq_params_t *p);

void ikfq_init(ikfq_t *s, const ikfq_formats_t *f, const ikfq_params_t *p);

/* What ikfq_init and ikfq_set_dt derive from the parameters and dt, as integers: a board with a fixed dt takes
 * them from a table (`python -m fcb_sim.estimation.native --constants` prints one) and links no double arithmetic. */
typedef struct {
    int32_t qg_shift, q_g0, k_rot, drift_noise, rest_r, rest_g2, rest_a2, bias_max, inv_g0, lat_half;
    int32_t pgg0, pdd0, g0_io, swing_max, swing_k;
    int64_t rest_time;
    int32_t dtq, dt2q, dthq, krq, kbq;
    int32_t decim; /* 0 (left out of an initializer) is 1 */
    int32_t lite;  /* 1: the variant that fits the M0 (ikfq_set_lite) */
} ikfq_consts_t;

void ikfq_init_q(ikfq_t *s, const ikfq_formats_t *f, const ikfq_consts_t *c);
void ikfq_consts(const ikfq_t *s, ikfq_consts_t *c); /* an initialised filter's constants (for the table) */
void ikfq_reset(ikfq_t *s);
void ikfq_set_dt(ikfq_t *s, double dt);
/* After ikfq_init: the gravity part every n-th sample (1, the default: every sample); resets the filter. */
void ikfq_set_decimation(ikfq_t *s, int32_t n);
/* After ikfq_init (and ikfq_set_decimation): 1 for the variant cut to fit the Cortex-M0 (ikf_lite.py: cheaper
 * products and series, the gravity part spread over decim samples), 0 for the exact twin; resets the filter. */
void ikfq_set_lite(ikfq_t *s, int32_t on);

/* One sample: gyro (rad/s) and specific force (m/s^2) in Q.io, chip frame z up; dt set by ikfq_set_dt. */
void ikfq_step(ikfq_t *s, const int32_t g[3], const int32_t a[3]);
/* The attitude carried latency ahead along the current rate (w, x, y, z in Q.quat). */
void ikfq_predicted(const ikfq_t *s, int32_t q[4]);

/* Host wrapper with the Python class's floats: skips non-finite samples and dt <= 0, converts, steps. */
void ikfq_update(ikfq_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt);
/* ikfq_update, then the predicted quaternion as doubles (one call a sample from Python). */
void ikfq_update_q(ikfq_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt,
                   double q[4]);

/* Host, for scoring (bench.filters): n samples (rows of gx gy gz ax ay az dt) through ikfq_update, and after each
 * the attitude predicted at each of nlat latencies (their half, Q.dt: ikfq_consts' lat_half) as doubles,
 * out[(i nlat + j) 4 + k]. The prediction never feeds back, so each is the filter's own output at that latency. */
void ikfq_run(ikfq_t *s, int32_t n, const double *rows, int32_t nlat, const int32_t *lat_half, double *out);

/* The state in a fixed order, for the tests and the Python wrapper (fcb_sim/estimation/native.py): qw qx qy qz vx vy dx
 * dy pvv pvg pvd pgg pgd pdd bx by bz rx ry rz gl[3] al[3] rest_t at_rest started phase fsum[1..3] qm[4] rate gxh gyh.
 * Returns the count, IKFQ_STATE_N. */
#define IKFQ_STATE_N 40
int ikfq_state(const ikfq_t *s, int64_t out[IKFQ_STATE_N]);
unsigned ikfq_size(void);

/* Q arithmetic (exposed for the tests): rounded half away from zero, saturated to int32. */
int32_t ikfq_mul(int64_t a, int64_t b, unsigned shift);
int32_t ikfq_div(int64_t a, int64_t b, unsigned shift);
int64_t ikfq_sqrt(int64_t a, unsigned frac);
int32_t ikfq_to_q(double x, unsigned frac);

#endif
