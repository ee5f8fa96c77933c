/* qb_flight.c: the flight core, fcb_sim/board/flight.py and control.py in C. Calibrated samples and sticks in, motor
 * commands out; the chip's axes are mapped to the body's once, where samples enter (p = gx, q = -gy, r = -gz).
 * Units: angles 10430 LSB per rad, rates in raw gyro LSB, lift and moments in ae^2 (control.py explains them). */
#include <math.h>
#include <string.h>

#include "qb_board.h"
#include "qb_estimator.h"

#define STILL_LSB (1.5 * 16.4) /* 1.5 deg/s of gyro (flight.py) */
#define HEADING_RATE_MIN_S 5.0
#define HEADING_RATE_WINDOW_S 60.0
#define TWO_PI (2.0 * 3.141592653589793)
static void heading_reset(qb_heading_t *h);
static void heading_step(qb_flight_t *fc, qb_real cgx, qb_real cgy, qb_real cgz, qb_real dt);

/* --- the RAW path's attitude filter: ikf_q.c, set up from integers -------------------------------------- */

/* ikf's default parameters in ikf_fixed.Formats(), from `python -m fcb_sim.estimation.native --constants 0.0025`
 * (tests/firmware/test_cboard.py checks they are still what it prints). Integers: the M0 links no double set-up. The
 * variant that fits the Cortex-M0 (ikf_lite.py: lite, its gravity part spread over decim = 4 samples). */
static const ikfq_formats_t IKF_FORMATS = {16, 30, 30, 24, 24, 28, 30};
static const ikfq_consts_t IKF_CONSTS = {
    .qg_shift = 5, .q_g0 = 335165867, .k_rot = 32768, .drift_noise = 70368744, .rest_r = 10737418,
    .rest_g2 = 5233287, .rest_a2 = 16384, .bias_max = 1464088, .inv_g0 = 109453805, .lat_half = 1342177,
    .pgg0 = 107374182, .pdd0 = 1073742, .g0_io = 642908, .swing_max = 869730877, .swing_k = 966367641,
    .rest_time = 1610612736, .dtq = 10737418, .dt2q = 107374, .dthq = 1342177, .krq = 21053761, .kbq = 5341999,
    .decim = 4, .lite = 1};
/* ikfq_to_q in qb_real: the same bits in double (host); float on the M0, where a double would link soft double */
static int32_t ikf_to_q(qb_real x, int frac)
{
    qb_real t = x * (qb_real)((int32_t)1 << frac); /* frac <= 30 */
    if (t >= (qb_real)INT32_MAX)
        return INT32_MAX;
    if (t <= (qb_real)INT32_MIN)
        return INT32_MIN;
    return t >= 0 ? (int32_t)(t + 0.5) : (int32_t)(t - 0.5); /* an int32 conversion: no 64-bit soft routine */
}

void qb_ikf_reset(qb_ikf_t *f)
{
    ikfq_init_q(&f->q, &IKF_FORMATS, &IKF_CONSTS);
    f->dt = 0.0;
}

/* The board's dt is measured (RTC ticks: 400 Hz on the RAW path, 200 Hz on the DMP's) and the Python filter
 * derives its dt constants from each new one: so does this, as ikfq_set_dt does. */
static void ikf_set_dt(qb_ikf_t *f, qb_real dt)
{
    const int sd = IKF_FORMATS.dt, cb = IKF_FORMATS.cov;
    const qb_real dn = f->q.decim * dt; /* the gravity part's step, as ikfq_set_dt */
    if (f->dt == dt)
        return;
    f->dt = dt;
    f->q.dtq = ikf_to_q(dn, sd);
    f->q.dt2q = ikf_to_q(dn * dn, sd);
    f->q.dthq = ikf_to_q(0.5 * dt, sd);
    f->q.krq = ikf_to_q(dn / (IKF_REST_TAU + dn), cb);
    f->q.kbq = ikf_to_q(dn / (IKF_REST_BIAS_TAU + dn), cb);
}

void qb_ikf_update(qb_ikf_t *f, qb_real gx, qb_real gy, qb_real gz, qb_real ax, qb_real ay, qb_real az, qb_real dt)
{
    const qb_real v[6] = {gx, gy, gz, ax, ay, az};
    int32_t g[3], a[3];
    int i;
    /* ikfq_update in qb_real: its doubles would cost the M0 the soft-double routines */
    if (!(dt > 0.0) || !isfinite(gx + gy + gz + ax + ay + az + dt))
        return; /* as ikf_fixed.py: the sample is skipped */
    for (i = 0; i < 3; i++) {
        g[i] = ikf_to_q(v[i], IKF_FORMATS.io);
        a[i] = ikf_to_q(v[3 + i], IKF_FORMATS.io);
    }
    if (f->q.started)
        ikf_set_dt(f, dt);
    ikfq_step(&f->q, g, a);
}

void qb_ikf_quaternion(const qb_ikf_t *f, qb_real q[4])
{
    const qb_real s = 1.0 / (qb_real)((int32_t)1 << IKF_FORMATS.quat);
    int32_t p[4];
    ikfq_predicted(&f->q, p);
    q[0] = p[0] * s;
    q[1] = p[1] * s;
    q[2] = p[2] * s;
    q[3] = p[3] * s;
}

void qb_ikf_angles(const qb_ikf_t *f, qb_real out[3])
{
    qb_real q[4], sp;
    qb_ikf_quaternion(f, q);
    out[0] = QM(atan2)(2.0 * (q[0] * q[1] + q[2] * q[3]), 1.0 - 2.0 * (q[1] * q[1] + q[2] * q[2]));
    sp = 2.0 * (q[0] * q[2] - q[1] * q[3]);
    sp = sp > 1.0 ? 1.0 : sp < -1.0 ? -1.0 : sp;
#ifdef QB_FLOAT
    out[1] = QM(atan2)(sp, QM(sqrt)((1.0 - sp) * (1.0 + sp))); /* asin(sp), without asinf's 700 B on the M0 */
#else
    out[1] = asin(sp); /* as the Python filter: the differential test compares the two */
#endif
    out[2] = QM(atan2)(2.0 * (q[0] * q[3] + q[1] * q[2]), 1.0 - 2.0 * (q[2] * q[2] + q[3] * q[3]));
}

/* --- est.attitude and est.height: which filter runs (param_bindings.py builds a new one on each change) --- */

void qb_flight_set_filter(qb_flight_t *fc, int filter, int fixed, qb_real k_gyro)
{
    fc->attitude = (uint8_t)filter;
    qb_ikf_reset(&fc->ikf);
#if QB_REPORT_EST
    qb_comp_init(&fc->comp, k_gyro, fixed);
#else
    (void)fixed;
    (void)k_gyro;
#endif
}

void qb_flight_set_height(qb_flight_t *fc, int complementary)
{
    fc->height_comp = (uint8_t)complementary;
    qb_flight_reset_height(fc, fc->calibrated ? fc->cal_pressure : SEA_LEVEL_PA);
}

void qb_flight_reset_height(qb_flight_t *fc, qb_real pressure)
{
    qb_height_reset(&fc->hest, pressure);
#if QB_REPORT_EST
    qb_hcomp_reset(&fc->hcomp, pressure);
#endif
    fc->height = fc->vz = 0.0;
}

#if QB_REPORT_EST
#define COMP(fc) ((fc)->attitude == QB_ATTITUDE_COMPLEMENTARY)
#define HCOMP(fc) ((fc)->height_comp)
#else
#define COMP(fc) 0
#define HCOMP(fc) 0
#endif

static void filter_reset(qb_flight_t *fc)
{
    qb_ikf_reset(&fc->ikf);
#if QB_REPORT_EST
    qb_comp_reset(&fc->comp);
#endif
}

static void filter_update(qb_flight_t *fc, qb_real gx, qb_real gy, qb_real gz, qb_real ax, qb_real ay, qb_real az,
                          qb_real dt)
{
#if QB_REPORT_EST
    if (COMP(fc)) {
        qb_comp_update(&fc->comp, gx, gy, gz, ax, ay, az, dt);
        return;
    }
#endif
    qb_ikf_update(&fc->ikf, gx, gy, gz, ax, ay, az, dt);
}

static void filter_quaternion(const qb_flight_t *fc, qb_real q[4])
{
#if QB_REPORT_EST
    if (COMP(fc)) {
        qb_comp_quaternion(&fc->comp, q);
        return;
    }
#endif
    qb_ikf_quaternion(&fc->ikf, q);
}

/* The RAW filter's roll, pitch, yaw (rad, z up). */
static void filter_angles(const qb_flight_t *fc, qb_real e[3])
{
#if QB_REPORT_EST
    if (COMP(fc)) {
        qb_comp_angles(&fc->comp, e);
        return;
    }
#endif
    qb_ikf_angles(&fc->ikf, e);
}

/* --- the flight core ------------------------------------------------------------------------------------- */

static qb_real gain_default(int id)
{
    const qb_param_spec_t *s = &QB_PARAMS[id - 1];
    return s->def * s->scale;
}

void qb_flight_init(qb_flight_t *fc)
{
    memset(fc, 0, sizeof *fc);
    fc->g.yaw_p = gain_default(QP_PARAM_YAW_P);
    fc->g.p1 = gain_default(QP_PARAM_P1);
    fc->g.p2 = gain_default(QP_PARAM_P2);
    fc->g.height_p = gain_default(QP_PARAM_HEIGHT_P);
    fc->g.height_d = gain_default(QP_PARAM_HEIGHT_D);
    fc->g.height_i = gain_default(QP_PARAM_HEIGHT_I);
    qb_height_init(&fc->hest);
    qb_ikf_reset(&fc->ikf);
    fc->attitude = QB_ATTITUDE_IKF;
    fc->panic_ae = PANIC_AE;
    fc->panic_scale = 1.0;
    fc->mode = QP_MODE_SAFE;
    fc->saz = -ACC_LSB_PER_G;
    fc->q[0] = 1.0;
    fc->a_off[2] = 0.0;
    fc->cal_pressure = 101325.0;
}

/* --- integer square root and mixing (control.py) ----------------------------------------------------------- */

static unsigned bit_length(uint32_t v)
{
    unsigned n = 0;
    while (v) {
        n++;
        v >>= 1;
    }
    return n;
}

/* The report's appendix C (clz first guess, two Newton-Raphson steps) plus the correction step: error <= 1. */
uint32_t qb_isqrt(uint32_t square)
{
    uint32_t xn;
    if (square == 0)
        return 0;
    xn = (uint32_t)1 << (bit_length(square) >> 1);
    xn = (xn + square / xn) >> 1;
    xn = (xn + square / xn) >> 1;
    if ((uint64_t)xn * xn > square)
        xn--;
    return xn;
}

static int32_t clamp_moment(qb_real v)
{
    return v > 1e9 ? 1000000000 : v < -1e9 ? -1000000000 : (int32_t)v;
}

void qb_mix(int32_t z, qb_real l, qb_real m, qb_real n, int armed, uint16_t out[4])
{
    /* moments past 1e9 ae^2 saturate every motor either way: clamped, they convert as int32 (no 64-bit float
     * conversion, which costs the M0 the soft double routines) */
    int64_t s = -(int64_t)z, li = 2 * (int64_t)clamp_moment(l), mi = 2 * (int64_t)clamp_moment(m);
    int64_t ni = clamp_moment(n);
    int64_t a[4];
    int32_t lo = armed ? AE_IDLE : 0;
    int j;
    a[0] = (s - ni + mi) >> 2;
    a[1] = (s + ni - li) >> 2;
    a[2] = (s - ni - mi) >> 2;
    a[3] = (s + ni + li) >> 2;
    for (j = 0; j < 4; j++) {
        /* beyond 4e6 the root is past AE_MAX whatever the last step's error: no 64-bit root needed */
        int32_t v = a[j] <= 0 ? 0 : a[j] > 4000000 ? AE_MAX + 1 : (int32_t)qb_isqrt((uint32_t)a[j]);
        out[j] = (uint16_t)(v < lo ? lo : v > AE_MAX ? AE_MAX : v);
    }
}

static int32_t lift_to_z(int32_t lift)
{
    int32_t ae;
    if (lift <= 0)
        return 0;
    ae = lift * LIFT_AE_MAX / 32767;
    return -4 * ae * ae;
}

/* --- samples --------------------------------------------------------------------------------------------- */

void qb_quaternion_to_euler(qb_real w, qb_real x, qb_real y, qb_real z, qb_real out[3])
{
    qb_real n2 = w * w + x * x + y * y + z * z, sp;
    if (n2 <= 0.0) {
        out[0] = out[1] = out[2] = 0.0;
        return;
    }
    if (QM(fabs)(n2 - 1.0) > 1e-9) {
        qb_real s = 1.0 / QM(sqrt)(n2);
        w *= s;
        x *= s;
        y *= s;
        z *= s;
    }
    out[0] = QM(atan2)(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y));
    sp = 2.0 * (w * y - x * z);
    if (-ASIN_FALLBACK < sp && sp < ASIN_FALLBACK)
        out[1] = QM(atan2)(sp, QM(sqrt)(1.0 - sp * sp)); /* the report's eq. 5 */
    else
        out[1] = sp >= 1.0 ? 1.5707963267948966 : sp <= -1.0 ? -1.5707963267948966 /* asin, clamped */
                 : QM(atan2)(sp, QM(sqrt)((1.0 - sp) * (1.0 + sp)));
    out[2] = QM(atan2)(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z));
}

void qb_flight_set_calibration(qb_flight_t *fc, const qb_real gyro[3], const qb_real accel[3], qb_real dmp_phi,
                               qb_real dmp_theta, qb_real pressure)
{
    memcpy(fc->g_off, gyro, sizeof fc->g_off);
    fc->a_off[0] = accel[0];
    fc->a_off[1] = accel[1];
    fc->a_off[2] = accel[2] - ACC_LSB_PER_G; /* gravity stays on z */
    fc->cal_dmp_phi = dmp_phi;
    fc->cal_dmp_theta = dmp_theta;
    fc->cal_pressure = pressure;
    fc->calibrated = 1;
    filter_reset(fc);
    qb_flight_reset_height(fc, pressure);
    heading_reset(&fc->heading_dmp);
    heading_reset(&fc->heading_raw);
    fc->drift_reported = 0;
    fc->height = fc->vz = 0.0;
}

void qb_flight_imu(qb_flight_t *fc, const int16_t raw[6], qb_real dt)
{
    qb_real cgx = raw[0] - fc->g_off[0], cgy = raw[1] - fc->g_off[1], cgz = raw[2] - fc->g_off[2];
    qb_real cax = raw[3] - fc->a_off[0], cay = raw[4] - fc->a_off[1], caz = raw[5] - fc->a_off[2];
    const qb_real s = 1.0 / ACC_LSB_PER_MS2;
    fc->sp = cgx;
    fc->sq = -cgy;
    fc->sr = -cgz;
    fc->sax = cax;
    fc->say = -cay;
    fc->saz = -caz;
    if (dt <= 0.0)
        return;
    /* a sideways jolt: a wall (or a hand) stopped the craft */
    fc->wall_quiet -= dt;
    if ((cax * s) * (cax * s) + (cay * s) * (cay * s) > WALL_ACC * WALL_ACC) {
        if (fc->wall_n < 255)
            fc->wall_n++;
    } else {
        fc->wall_n = 0;
    }
    if (fc->wall_n >= WALL_SAMPLES && fc->wall_quiet <= 0.0) {
        fc->walls = 1;
        fc->wall_quiet = WALL_REPEAT_S;
    }
    filter_update(fc, cgx * RAD_S_PER_LSB, cgy * RAD_S_PER_LSB, cgz * RAD_S_PER_LSB, cax * s, cay * s, caz * s, dt);
    /* no DMP (RAW mode): the height estimator takes the filter's attitude at 100 Hz, as fast as the DMP's */
    fc->n_imu++;
    if (!fc->have_dmp && !(fc->n_imu & 3))
        filter_quaternion(fc, fc->q);
#if QB_REPORT_EST
    if (HCOMP(fc)) {
        qb_hcomp_update_imu(&fc->hcomp, cax * s, cay * s, caz * s, fc->q[0], fc->q[1], fc->q[2], fc->q[3], dt);
        fc->height = fc->hcomp.height;
        fc->vz = fc->hcomp.vz;
    } else
#endif
    {
        qb_height_update_imu(&fc->hest, cax * s, cay * s, caz * s, fc->q[0], fc->q[1], fc->q[2], fc->q[3], dt);
        fc->height = fc->hest.height;
        fc->vz = fc->hest.vz;
    }
    heading_step(fc, cgx, cgy, cgz, dt);
}

static qb_real wrap(qb_real a)
{
    return a - TWO_PI * QM(floor)((a + 3.141592653589793) / TWO_PI);
}

static void heading_still_end(qb_heading_t *h)
{
    h->n = 0;
    h->t = h->y = h->st = h->sy = h->sty = h->stt = 0.0;
}

static void heading_reset(qb_heading_t *h)
{
    h->offset = 0.0;
    h->have_prev = 0;
    h->prev = 0.0;
    heading_still_end(h);
}

/* heading.py's HeadingHold.update: still, every change is drift (and the stretch's slope its rate); else the
 * learnt rate is taken out. Returns the corrected heading. */
static qb_real heading_update(qb_heading_t *h, qb_real psi, int still, qb_real dt)
{
    qb_real d = h->have_prev ? wrap(psi - h->prev) : 0.0;
    h->prev = psi;
    h->have_prev = 1;
    if (still) {
        qb_real den;
        h->offset += d;
        if (h->t >= HEADING_RATE_WINDOW_S)
            heading_still_end(h);
        h->t += dt;
        h->y += d;
        h->n++;
        h->st += h->t;
        h->sy += h->y;
        h->sty += h->t * h->y;
        h->stt += h->t * h->t;
        den = (qb_real)h->n * h->stt - h->st * h->st;
        if (h->t >= HEADING_RATE_MIN_S && den > 0.0)
            h->rate = ((qb_real)h->n * h->sty - h->st * h->sy) / den;
    } else {
        if (h->n)
            heading_still_end(h);
        h->offset += h->rate * dt;
    }
    return wrap(psi - h->offset);
}

static void heading_step(qb_flight_t *fc, qb_real cgx, qb_real cgy, qb_real cgz, qb_real dt)
{
    int quiet = -STILL_LSB < cgx && cgx < STILL_LSB && -STILL_LSB < cgy && cgy < STILL_LSB && -STILL_LSB < cgz &&
                cgz < STILL_LSB;
    int still;
    qb_real t, e[3];
    fc->still_s = quiet && !HCOMP(fc) && fc->hest.on_ground ? fc->still_s + dt : 0.0; /* Figure 10 has no ground test */
    fc->head_dt += dt;
    if (++fc->n_head < HEADING_EVERY)
        return;
    still = fc->still_s >= STILL_S;
    if (fc->still && !still) { /* leaving the pad: report the drift */
        const qb_heading_t *h = fc->psi_raw ? &fc->heading_raw : &fc->heading_dmp;
        int32_t d = (int32_t)QM(lround)(h->offset * 18000.0 / 3.141592653589793) - fc->drift_reported;
        if (d >= HEADING_LIFTOFF_CDEG || d <= -HEADING_LIFTOFF_CDEG)
            fc->drift_reported = -(1 << 30);
    }
    fc->still = (uint8_t)still;
    t = fc->head_dt;
    fc->n_head = 0;
    fc->head_dt = 0.0;
    fc->hpsi_dmp = heading_update(&fc->heading_dmp, fc->dmp_psi, still, t);
    filter_angles(fc, e);
    fc->hpsi_raw = heading_update(&fc->heading_raw, -e[2], still, t);
}

void qb_flight_dmp(qb_flight_t *fc, const float q[4])
{
    qb_real e[3];
    qb_quaternion_to_euler(q[0], q[1], q[2], q[3], e);
    fc->dmp_phi = e[0] - fc->cal_dmp_phi;
    fc->dmp_theta = -e[1] - fc->cal_dmp_theta;
    fc->dmp_psi = -e[2];
    fc->q[0] = q[0];
    fc->q[1] = q[1];
    fc->q[2] = q[2];
    fc->q[3] = q[3];
    fc->have_dmp = 1;
}

void qb_flight_baro(qb_flight_t *fc, qb_real pressure_pa, qb_real dt)
{
#if QB_REPORT_EST
    if (HCOMP(fc)) {
        qb_hcomp_update_baro(&fc->hcomp, pressure_pa, dt);
        return;
    }
#endif
    qb_height_update_baro(&fc->hest, pressure_pa, dt);
}

/* --- modes and control ------------------------------------------------------------------------------------ */

qb_real qb_flight_move_setpoint(qb_flight_t *fc, qb_real dm, qb_real lo, qb_real hi)
{
    qb_real sp = fc->setpoint + dm; /* fcb_sim/board/flight.py's move_setpoint */
    if (dm > 0.0)
        sp = sp < (hi > fc->setpoint ? hi : fc->setpoint) ? sp : (hi > fc->setpoint ? hi : fc->setpoint);
    else
        sp = sp > (lo < fc->setpoint ? lo : fc->setpoint) ? sp : (lo < fc->setpoint ? lo : fc->setpoint);
    fc->sp_offset += sp - fc->setpoint;
    fc->setpoint = sp;
    return sp;
}

void qb_flight_enter_mode(qb_flight_t *fc, uint8_t mode, int32_t lift)
{
    if (mode == QP_MODE_HEIGHT) {
        fc->sp_from_est = !HCOMP(fc); /* Figure 10 has no captured height */
        fc->sp_cap0 = HCOMP(fc) ? 0.0 : qb_height_capture(&fc->hest);
        fc->sp_base = fc->height;
        fc->sp_offset = 0.0;
        fc->setpoint = fc->sp_base;
        fc->lift_entry = lift;
        fc->z_base = lift_to_z(lift);
        fc->z_int = 0.0;
        fc->height_raw = fc->mode == QP_MODE_RAW || (fc->mode == QP_MODE_HEIGHT && fc->height_raw);
    } else if (mode == QP_MODE_PANIC) {
        fc->panic_scale = 1.0;
        fc->panic_landed = 0;
        fc->land_s = 0.0;
        fc->panic_start = fc->panic_level = (fc->ae[0] + fc->ae[1] + fc->ae[2] + fc->ae[3]) / 4.0;
        fc->panic_i = fc->panic_start - fc->panic_ae;
    } else if (mode == QP_MODE_CALIBRATION) {
        fc->cal_dmp_phi = fc->cal_dmp_theta = 0.0;
    }
    if (mode == QP_MODE_RAW)
        fc->have_dmp = 0;
    fc->mode = mode;
}

/* The angles the loops fly on: the on-board filter's in RAW (and HEIGHT entered from RAW), else the DMP's. */
static int on_filter(const qb_flight_t *fc, uint8_t mode)
{
    return mode == QP_MODE_RAW || (mode == QP_MODE_HEIGHT && fc->height_raw);
}

/* The angles shown and flown on: the on-board filter's (`filter`) or the DMP's. */
static void follow(qb_flight_t *fc, int filter)
{
    if (filter) {
        qb_real e[3];
        filter_angles(fc, e);
        fc->phi = e[0];
        fc->theta = -e[1];
    } else {
        fc->phi = fc->dmp_phi;
        fc->theta = fc->dmp_theta;
    }
    fc->psi_raw = (uint8_t)filter;
}

static qb_real panic_descent_rate(qb_real height_m)
{
    qb_real f = (height_m - PANIC_SLOW_BELOW_M) / (PANIC_FAST_ABOVE_M - PANIC_SLOW_BELOW_M);
    f = f < 0.0 ? 0.0 : f > 1.0 ? 1.0 : f;
    return PANIC_SLOW_M_S + (PANIC_FAST_M_S - PANIC_SLOW_M_S) * f;
}

static void panic_motors(qb_flight_t *fc, qb_real scale, qb_real dt, uint16_t out[4])
{
    int32_t level;
    if (fc->panic_hold) {
        fc->panic_level = fc->panic_ae < fc->panic_start ? fc->panic_ae : fc->panic_start;
    } else if (!fc->panic_landed && dt > 0.0) {
        qb_real err = -panic_descent_rate(fc->height) - fc->vz, floor_, lvl;
        qb_real i = fc->panic_i + PANIC_KI * err * dt;
        int still;
        fc->panic_i = i < -fc->panic_ae ? -fc->panic_ae : i > PANIC_MAX_AE ? PANIC_MAX_AE : i;
        floor_ = PANIC_MIN_FRAC * fc->panic_ae;
        if (fc->panic_start < floor_)
            floor_ = fc->panic_start;
        lvl = fc->panic_ae + PANIC_KP * err + fc->panic_i;
        lvl = lvl > PANIC_MAX_AE ? PANIC_MAX_AE : lvl;
        lvl = lvl < floor_ ? floor_ : lvl;
        still = lvl < PANIC_LAND_FRAC * fc->panic_ae && QM(fabs)(fc->vz) < PANIC_LAND_VZ;
        fc->land_s = still ? fc->land_s + dt : 0.0;
        fc->panic_landed = fc->land_s >= PANIC_LAND_S;
        fc->panic_level = lvl;
    }
    scale = scale < 0.0 ? 0.0 : scale > 1.0 ? 1.0 : scale;
    level = (int32_t)(fc->panic_level * scale);
    if (fc->calibrated && level > 0) {
        const qb_gains_t *g = &fc->g;
        qb_real lm, mm; /* levelled on the DMP's angles (PANIC's sensor path), as the Python board */
        lm = g->p2 * (g->p1 * (0.0 - fc->dmp_phi * ANGLE_LSB_PER_RAD) - fc->sp);
        mm = g->p2 * (g->p1 * (0.0 - fc->dmp_theta * ANGLE_LSB_PER_RAD) - fc->sq);
        qb_real nm = g->yaw_p * (0.0 - fc->sr);
        qb_mix(-4 * level * level, lm, mm, nm, 0, out);
        return;
    }
    out[0] = out[1] = out[2] = out[3] = (uint16_t)level;
}

static qb_real height_z(qb_flight_t *fc, int32_t lift, qb_real dt)
{
    const qb_gains_t *g = &fc->g;
    int32_t d = lift - fc->lift_entry;
    qb_real sp, sp_mm, h_mm, z;
    int sat;
    if (d > HEIGHT_STICK_DEADBAND || d < -HEIGHT_STICK_DEADBAND)
        fc->sp_offset += d / 32767.0 * HEIGHT_STICK_RATE * dt;
    sp = fc->sp_base + fc->sp_offset;
    if (fc->sp_from_est)
        sp += fc->hest.captured_height - fc->sp_cap0;
    fc->setpoint = sp;
    sp_mm = fc->setpoint * 1000.0;
    h_mm = fc->height * 1000.0;
    z = fc->z_base - g->height_p * (sp_mm - h_mm) + g->height_d * (fc->vz * 1000.0) - fc->z_int;
    sat = z > 0.0;
    if (sat)
        z = 0.0;
    if (g->height_i > 0.0) {
        /* saturated: only unwinding steps count (anti-windup), and the integral is clamped */
        qb_real step = g->height_i * (sp_mm - h_mm) * dt, i;
        if (!(sat && step * fc->z_int > 0.0)) {
            i = fc->z_int + step;
            fc->z_int = i > HEIGHT_I_LIMIT ? HEIGHT_I_LIMIT : i < -HEIGHT_I_LIMIT ? -HEIGHT_I_LIMIT : i;
        }
    }
    return z;
}

void qb_flight_control(qb_flight_t *fc, uint8_t mode, const int32_t sticks[4], qb_real dt, uint16_t out[4])
{
    const qb_gains_t *g = &fc->g;
    int32_t roll = sticks[0], pitch = sticks[1], yaw = sticks[2], lift = sticks[3];
    if (mode != fc->mode)
        qb_flight_enter_mode(fc, mode, lift);
    if (mode == QP_MODE_FULL || mode == QP_MODE_HEIGHT || mode == QP_MODE_RAW) {
        qb_real lm, mm, nm, z;
        follow(fc, on_filter(fc, mode));
        lm = g->p2 * (g->p1 * ((roll >> STICK_ANGLE_SHIFT) - fc->phi * ANGLE_LSB_PER_RAD) - fc->sp);
        mm = g->p2 * (g->p1 * ((pitch >> STICK_ANGLE_SHIFT) - fc->theta * ANGLE_LSB_PER_RAD) - fc->sq);
        nm = g->yaw_p * ((yaw >> STICK_YAW_SHIFT) - fc->sr);
        z = mode == QP_MODE_HEIGHT ? height_z(fc, lift, dt) : lift_to_z(lift);
        qb_mix((int32_t)z, lm, mm, nm, 1, out);
    } else if (mode == QP_MODE_MANUAL || mode == QP_MODE_YAW) {
        qb_real nm;
        follow(fc, 0);
        nm = mode == QP_MODE_YAW ? g->yaw_p * ((yaw >> STICK_YAW_SHIFT) - fc->sr) : (qb_real)yaw * MANUAL_N_GAIN;
        qb_mix(lift_to_z(lift), (qb_real)roll * MANUAL_LM_GAIN, (qb_real)pitch * MANUAL_LM_GAIN, nm, 1, out);
    } else {
        /* No attitude loop runs (SAFE, CALIBRATION, PANIC): the angles shown follow the sensor path that runs, the
         * DMP's or, without it (RAW's path), the filter's, so a flight that ended tilted is not shown tilted on the
         * pad. */
        follow(fc, !fc->have_dmp);
        if (mode == QP_MODE_PANIC)
            panic_motors(fc, fc->panic_scale, dt, out);
        else
            out[0] = out[1] = out[2] = out[3] = 0;
    }
    memcpy(fc->ae, out, sizeof fc->ae);
    /* the height estimator's on-the-ground test: no motor could lift the craft */
    fc->hest.motors_off = out[0] < GROUND_AE && out[1] < GROUND_AE && out[2] < GROUND_AE && out[3] < GROUND_AE;
    /* the thrust model's hint: the sum of ae², scaled by the pack (the ESCs' speed follows its voltage) */
    fc->hest.thrust_hint = (qb_real)(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]) *
                           fc->hest.supply_sq;
}

int qb_flight_pending_heading_drift(qb_flight_t *fc, int32_t *cdeg)
{
    const qb_heading_t *h = fc->psi_raw ? &fc->heading_raw : &fc->heading_dmp;
    int32_t d = (int32_t)QM(lround)(h->offset * 18000.0 / 3.141592653589793);
    int32_t diff = d - fc->drift_reported;
    if (diff < HEADING_REPORT_CDEG && diff > -HEADING_REPORT_CDEG)
        return 0;
    fc->drift_reported = d;
    *cdeg = d;
    return 1;
}

int32_t qb_flight_pending_contact(qb_flight_t *fc)
{
    if (!HCOMP(fc) && fc->hest.stops != fc->stops_seen) {
        qb_real mm = QM(lround)(fc->hest.stop_speed * 1000.0);
        fc->stops_seen = fc->hest.stops;
        return (int32_t)((uint32_t)(fc->hest.stop_kind == 2 ? QP_CONTACT_KIND_CEILING : QP_CONTACT_KIND_GROUND) << 16 |
                         (uint32_t)(mm > 65535.0 ? 65535.0 : mm));
    }
    if (fc->walls) {
        fc->walls = 0;
        return (int32_t)((uint32_t)QP_CONTACT_KIND_WALL << 16);
    }
    return -1;
}

void qb_flight_attitude_cdeg(const qb_flight_t *fc, int32_t out[3])
{
    const qb_real k = 18000.0 / 3.141592653589793;
    out[0] = (int32_t)QM(lround)(fc->phi * k);
    out[1] = (int32_t)QM(lround)(fc->theta * k);
    qb_real psi = fc->psi_raw ? fc->hpsi_raw : fc->hpsi_dmp; /* relative, the drift learnt at rest out */
    out[2] = (int32_t)QM(lround)(psi * k);
}
