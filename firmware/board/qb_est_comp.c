/* qb_est_comp.c: the lab report's complementary attitude filter (eq. 1) and Figure 10's height estimator, the
 * Python board's fcb_sim/estimation/complementary.py and height.py (HeightEstimator) in C, operation for operation:
 * in double on the host the same bits (the differential test compares them), in float on a QB_FLOAT build. The
 * Q16.16 filter is integer arithmetic: the same bits everywhere (fcb_sim/estimation/fixed.py's libfixmath). */
#include <math.h>
#include <string.h>

#include "qb_board.h"
#include "qb_estimator.h"

#if QB_REPORT_EST

#define FX_MAX INT32_MAX
#define FX_MIN INT32_MIN
#define PI_R 3.141592653589793

static const int32_t KNOTS[FX_ATAN2_N] = FX_ATAN2_KNOTS;
static const int16_t CORRECTION[FX_ATAN2_N] = FX_ATAN2_CORRECTION;

/* --- Q16.16 with libfixmath's semantics (fixed.py; wider intermediates where Python's ints are unbounded) -------- */

static int32_t wrap32(int64_t a)
{
    return (int32_t)(uint32_t)(uint64_t)a;
}

static int32_t fx_from(qb_real x) /* fix16_from_float: half away from zero, saturating */
{
    qb_real t = x * 65536.0;
    if (t >= 0.0)
        return t < 2147483647.0 ? (int32_t)(t + 0.5) : FX_MAX;
    return t > -2147483648.0 ? (int32_t)(t - 0.5) : FX_MIN; /* NaN: the minimum, as fixed.py */
}

static int32_t fx_sat(int64_t s) /* fix16_sadd / fix16_ssub's clip */
{
    return s > FX_MAX ? FX_MAX : s < FX_MIN ? FX_MIN : (int32_t)s;
}

static int32_t fx_smul(int32_t a, int32_t b)
{
    int64_t p = (int64_t)a * b, r;
    if (p < 0) {
        if ((p >> 47) != -1)
            return (a >= 0) == (b >= 0) ? FX_MAX : FX_MIN;
        p -= 1; /* libfixmath: rounds -1/2 correctly */
    } else if (p >> 47) {
        return (a >= 0) == (b >= 0) ? FX_MAX : FX_MIN;
    }
    r = (p >> 16) + ((p & 0x8000) >> 15);
    return r <= FX_MAX ? (int32_t)r : FX_MAX;
}

static int32_t fx_mul(int32_t a, int32_t b) /* fix16_mul: its overflow flag is the minimum's bits */
{
    int64_t p = (int64_t)a * b;
    if (p < 0) {
        if ((p >> 47) != -1)
            return FX_MIN;
        p -= 1;
    } else if (p >> 47) {
        return FX_MIN;
    }
    return wrap32((p >> 16) + ((p & 0x8000) >> 15));
}

static int32_t fx_div(int64_t a, int64_t b) /* fix16_div */
{
    uint64_t q, r;
    if (b == 0)
        return FX_MIN;
    q = ((uint64_t)(a < 0 ? -a : a) << 17) / (uint64_t)(b < 0 ? -b : b);
    if (q >= 0xFFFFFFFFu)
        return FX_MIN; /* fix16_overflow */
    r = (q + 1) >> 1;
    return (a < 0) != (b < 0) ? (int32_t)-(int64_t)r : (int32_t)r;
}

static int32_t fx_sqrt(int32_t a) /* fix16_sqrt: the rounded root of |a|, a's sign */
{
    uint64_t n = (uint64_t)(a < 0 ? -(int64_t)a : a) << 16, r = 0, bit = (uint64_t)1 << 62;
    while (bit > n)
        bit >>= 2;
    while (bit) { /* digit by digit: n ends as the remainder, N - r^2 */
        if (n >= r + bit) {
            n -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
        bit >>= 2;
    }
    if (n > r)
        r++;
    return a < 0 ? -(int32_t)r : (int32_t)r;
}

static int64_t fx_atan2(int64_t y, int32_t x) /* libfixmath's cubic */
{
    int64_t ay = y < 0 ? -y : y, angle;
    int32_t r, r3;
    if (x >= 0) {
        r = fx_div(x - ay, x + ay);
        r3 = fx_mul(fx_mul(r, r), r);
        angle = (int64_t)fx_mul(FX_ATAN_C3, r3) - fx_mul(FX_ATAN_C1, r) + FX_PI_DIV_4;
    } else {
        r = fx_div(x + ay, ay - x);
        r3 = fx_mul(fx_mul(r, r), r);
        angle = (int64_t)fx_mul(FX_ATAN_C3, r3) - fx_mul(FX_ATAN_C1, r) + FX_THREE_PI_DIV_4;
    }
    angle = wrap32(angle);
    return y < 0 ? -angle : angle;
}

/* fix16_atan2 plus the report's piecewise-linear correction (section 3.10; fixed.py's atan2_corrected). */
static int64_t fx_atan2c(int64_t y, int32_t x)
{
    int64_t a = fx_atan2(y, x), m = a < 0 ? -a : a, u = m % FX_HALF_PI, n, d, c;
    int mirrored = u > FX_PI_DIV_4, i = 0;
    if (mirrored)
        u = FX_HALF_PI - u;
    while (i + 1 < FX_ATAN2_N && KNOTS[i + 1] <= u) /* bisect_right - 1 */
        i++;
    if (i > FX_ATAN2_N - 2)
        i = FX_ATAN2_N - 2;
    n = (int64_t)(CORRECTION[i + 1] - CORRECTION[i]) * (u - KNOTS[i]);
    d = KNOTS[i + 1] - KNOTS[i];
    c = n / d;
    if (n % d != 0 && n < 0)
        c -= 1; /* Python's // floors */
    c += CORRECTION[i];
    if (mirrored)
        c = -c;
    return a < 0 ? a - c : a + c;
}

static int64_t fx_wrap_pi(int64_t a)
{
    return a > FX_PI ? a - 2 * FX_PI : a <= -FX_PI ? a + 2 * FX_PI : a;
}

/* --- eq. 1 ------------------------------------------------------------------------------------------------ */

static qb_real wrap_pi(qb_real a)
{
    return a > PI_R ? a - 2.0 * PI_R : a <= -PI_R ? a + 2.0 * PI_R : a;
}

void qb_comp_init(qb_comp_t *f, qb_real k_gyro, int fixed)
{
    f->fixed = (uint8_t)(fixed != 0);
    f->k_gyro = k_gyro;
    f->k_acc = FX_ONE - fx_from(k_gyro);
    qb_comp_reset(f);
}

void qb_comp_reset(qb_comp_t *f)
{
    f->roll = f->pitch = f->yaw = 0.0;
    f->r = f->p = f->y = 0;
    f->started = 0;
}

static void update_q16(qb_comp_t *f, qb_real gx, qb_real gy, qb_real gz, qb_real ax, qb_real ay, qb_real az,
                       qb_real dt)
{
    int32_t fax = fx_from(ax), fay = fx_from(ay), faz = fx_from(az), fdt, r, p, ka = f->k_acc;
    int64_t roll_acc = fx_atan2c(fay, faz);
    int64_t pitch_acc = fx_atan2c(-(int64_t)fax, fx_sqrt(fx_sat((int64_t)fx_smul(fay, fay) + fx_smul(faz, faz))));
    if (!f->started) {
        f->r = (int32_t)roll_acc;
        f->p = (int32_t)pitch_acc;
        f->started = 1;
        return;
    }
    fdt = fx_from(dt);
    r = fx_sat((int64_t)f->r + fx_smul(fx_from(gx), fdt));
    f->r = (int32_t)fx_wrap_pi(fx_sat((int64_t)r + fx_smul(ka, (int32_t)fx_wrap_pi(fx_sat(roll_acc - r)))));
    p = fx_sat((int64_t)f->p + fx_smul(fx_from(gy), fdt));
    f->p = fx_sat((int64_t)p + fx_smul(ka, fx_sat(pitch_acc - p)));
    f->y = wrap32(fx_wrap_pi((int64_t)f->y + fx_smul(fx_from(gz), fdt)));
}

void qb_comp_update(qb_comp_t *f, qb_real gx, qb_real gy, qb_real gz, qb_real ax, qb_real ay, qb_real az, qb_real dt)
{
    qb_real roll_acc, pitch_acc, ka, roll, pitch;
    if (f->fixed) {
        update_q16(f, gx, gy, gz, ax, ay, az, dt);
        return;
    }
    roll_acc = QM(atan2)(ay, az);
    pitch_acc = QM(atan2)(-ax, QM(sqrt)(ay * ay + az * az));
    if (!f->started) {
        f->roll = roll_acc;
        f->pitch = pitch_acc;
        f->started = 1;
        return;
    }
    ka = 1.0 - f->k_gyro;
    /* "prediction + K_acce (measurement - prediction)", the roll's difference wrapped (complementary.py) */
    roll = f->roll + gx * dt;
    f->roll = wrap_pi(roll + ka * wrap_pi(roll_acc - roll));
    pitch = f->pitch + gy * dt;
    f->pitch = pitch + ka * (pitch_acc - pitch);
    f->yaw = wrap_pi(f->yaw + gz * dt);
}

void qb_comp_angles(const qb_comp_t *f, qb_real out[3])
{
    if (f->fixed) {
        out[0] = f->r / 65536.0;
        out[1] = f->p / 65536.0;
        out[2] = f->y / 65536.0;
    } else {
        out[0] = f->roll;
        out[1] = f->pitch;
        out[2] = f->yaw;
    }
}

void qb_comp_quaternion(const qb_comp_t *f, qb_real q[4]) /* base.py's euler_to_quaternion */
{
    qb_real e[3], cr, sr, cp, sp, cy, sy;
    qb_comp_angles(f, e);
    cr = QM(cos)(0.5 * e[0]);
    sr = QM(sin)(0.5 * e[0]);
    cp = QM(cos)(0.5 * e[1]);
    sp = QM(sin)(0.5 * e[1]);
    cy = QM(cos)(0.5 * e[2]);
    sy = QM(sin)(0.5 * e[2]);
    q[0] = cr * cp * cy + sr * sp * sy;
    q[1] = sr * cp * cy - cr * sp * sy;
    q[2] = cr * sp * cy + sr * cp * sy;
    q[3] = cr * cp * sy - sr * sp * cy;
}

/* --- Figure 10 (HeightEstimator with baro_highpass_hz 0, no median, no spike gate: gen_c.py checks) ------- */

void qb_hcomp_reset(qb_hcomp_t *h, qb_real pressure_pa)
{
    memset(h, 0, sizeof *h);
    if (!(pressure_pa > 0.0))
        pressure_pa = SEA_LEVEL_PA; /* Python raises; the board keeps a sane reference (as qb_height.c) */
    h->p_ref = pressure_pa;
    h->k_pa_per_m = pressure_pa * G * M_AIR / (R_GAS * T_ROOM);
}

void qb_hcomp_update_baro(qb_hcomp_t *h, qb_real pressure_pa, qb_real dt)
{
    qb_real x, lp, prev;
    if (dt <= 0.0)
        return;
    if (pressure_pa > 0.0) /* eq. 2 */
        x = h->p_ref / h->k_pa_per_m * QM(log)(h->p_ref / pressure_pa);
    else
        x = (pressure_pa - h->p_ref) / -h->k_pa_per_m;
    h->baro_raw = x;
    lp = dt / (HC_BARO_LOWPASS_S + dt);
    /* velocity path: the (here open) high-pass, the low-pass, the difference quotient */
    h->hp_b_out = h->hp_b_out + x - h->hp_b_in;
    prev = h->lp_v;
    h->lp_v = prev + lp * (h->hp_b_out - prev);
    h->baro_vz = (h->lp_v - prev) / dt;
    /* position path: the reading low-passed */
    h->hp_b_in = x;
    h->baro_height += lp * (x - h->baro_height);
}

void qb_hcomp_update_imu(qb_hcomp_t *h, qb_real ax, qb_real ay, qb_real az, qb_real qw, qb_real qx, qb_real qy,
                         qb_real qz, qb_real dt)
{
    qb_real a_up, k, a, av, ap;
    if (dt <= 0.0)
        return;
    /* the earth-up specific force (third row of R(q)) minus gravity */
    a_up = 2.0 * (qx * qz - qw * qy) * ax + 2.0 * (qy * qz + qw * qx) * ay + (qw * qw - qx * qx - qy * qy + qz * qz) * az
           - G;
    if (!h->a_primed) { /* the high-pass starts at its input: a constant offset does not kick the speed */
        h->hp_a_in = a_up;
        h->a_primed = 1;
    }
    k = HC_TAU_HP_ACC / (HC_TAU_HP_ACC + dt);
    h->hp_a_out = k * (h->hp_a_out + a_up - h->hp_a_in);
    h->hp_a_in = a_up;
    a = h->hp_a_out;
    h->az_earth = a;
    av = HC_TAU_V / (HC_TAU_V + dt);
    h->vz = av * (h->vz + a * dt) + (1.0 - av) * h->baro_vz;
    ap = HC_TAU_P / (HC_TAU_P + dt);
    h->height = ap * (h->height + h->vz * dt) + (1.0 - ap) * h->baro_height;
}

#else
typedef int qb_est_comp_left_out; /* ISO C wants a declaration in every translation unit */
#endif /* QB_REPORT_EST */
