/* qb_ikf.c: the RAW path's attitude filter, ikf's fixed-point twin: fcb_sim/estimation/ikf_fixed.py step for
 * step in 32-bit integers (64-bit products), with the same Q formats (io Q16.16; dt and the quaternion Q2.30;
 * bias, V and G_h Q8.24; D Q4.28; covariances and gains Q2.30), the same rounding (half away from zero) and the
 * same saturation. The algorithm and why each format: docs/attitude.md. The constants below are
 * ikf_fixed.py's for ikf's default parameters (tau 4.5 s, k_rot 0.5, latency 2.5 ms, rest 2 deg/s, 0.5 m/s^2 for
 * 1.5 s, bias at most 5 deg/s). */
#include <math.h>
#include <string.h>

#include "qb_board.h"

#define IO 16
#define DT 30
#define QB 30 /* the quaternion */
#define BB 24 /* bias */
#define VB 24 /* V, G_h */
#define DB 28 /* D */
#define CB 30 /* covariances */
#define I32_MAX 0x7FFFFFFFLL
#define I32_MIN (-0x7FFFFFFFLL - 1)

#define QG_SHIFT 5
static const int32_t Q_G0 = 335165867;  /* q_g0, Q(cov + 5) */
static const int32_t K_ROT = 32768;     /* 0.5, Q16 */
static const int32_t DRIFT_NOISE = 70368744; /* Q(cov + 16) */
static const int32_t REST_R = 10737418; /* 0.01, Q.cov */
static const int32_t REST_G2 = 5233287; /* (2 deg/s)^2, Q(2 bias - 16) */
static const int32_t REST_A2 = 16384;   /* 0.5^2, Q16 */
static const int32_t BIAS_MAX = 1464088; /* 5 deg/s, Q.bias */
static const int32_t INV_G0 = 109453805; /* 1 / 9.81, Q.quat */
static const int32_t LAT_HALF = 1342177; /* latency / 2, Q.dt */
static const int32_t P_GG0 = 107374182; /* 0.1, Q.cov */
static const int32_t DRIFT_INIT = 1073742; /* 1e-3, Q.cov */
static const int32_t G0_IO = 642908;    /* 9.81, Q16 */
static const int64_t REST_TIME_Q = 1610612736; /* 1.5 s, Q.dt (the time at rest counts as dt does) */
#define REST_TAU 0.5
#define REST_BIAS_TAU 2.0

/* On the M0 the 64-bit multiplies and shifts are library calls: one copy of mul, called, is 4 KB smaller than
 * the hundred copies -Os would inline. */
#if defined(QB_FLOAT) && defined(__GNUC__)
#define QB_NOINLINE __attribute__((noinline))
#else
#define QB_NOINLINE
#endif

static QB_NOINLINE int32_t sat(int64_t v)
{
    return (int32_t)(v > I32_MAX ? I32_MAX : v < I32_MIN ? I32_MIN : v);
}


/* (a * b) >> shift, rounded half away from zero, saturated (fix16_mul with another shift); a and b are int64 where
 * Python's unbounded sums feed it (they stay far inside int32 in use) */
static QB_NOINLINE int32_t mul64(int64_t a, int64_t b, int shift)
{
    int64_t p = a * b, h = (int64_t)1 << (shift - 1);
    return sat(p >= 0 ? (p + h) >> shift : -((h - p) >> shift));
}

static QB_NOINLINE int32_t mul(int32_t a, int32_t b, int shift)
{
    return mul64(a, b, shift);
}

/* (a << shift) / b, rounded half away from zero, saturated */
static int32_t qdiv(int64_t a, int64_t b, int shift)
{
    uint64_t n, d, r;
    if (b == 0)
        return a >= 0 ? (int32_t)I32_MAX : (int32_t)I32_MIN;
    n = (uint64_t)(a < 0 ? -a : a) << shift;
    d = (uint64_t)(b < 0 ? -b : b);
    r = (2 * n + d) / (2 * d);
    return sat((a < 0) != (b < 0) ? -(int64_t)r : (int64_t)r);
}

static uint64_t isqrt64(uint64_t n)
{
    uint64_t r = 0, bit = (uint64_t)1 << 62;
    while (bit > n)
        bit >>= 2;
    while (bit) {
        if (n >= r + bit) {
            n -= r + bit;
            r = (r >> 1) + bit;
        } else {
            r >>= 1;
        }
        bit >>= 2;
    }
    return r;
}

/* Square root of a Q(32-frac).frac number in the same format, rounded */
static int32_t qsqrt(int64_t a, int frac)
{
    uint64_t n, r;
    if (a <= 0)
        return 0;
    if (a > I32_MAX)
        a = I32_MAX; /* never in use: the sums stay within int32 */
    n = (uint64_t)a << frac;
    r = isqrt64(n);
    return sat((int64_t)(n - r * r > r ? r + 1 : r));
}

static int32_t to_q(qb_real x, int frac)
{
    qb_real t = x * (qb_real)((int32_t)1 << frac); /* frac <= 30 */
    if (t >= (qb_real)I32_MAX)
        return (int32_t)I32_MAX;
    if (t <= (qb_real)I32_MIN)
        return (int32_t)I32_MIN;
    /* inside the int32 range now: an int32 conversion (a 64-bit one costs the M0 the soft double routines) */
    return t >= 0 ? (int32_t)(t + 0.5) : (int32_t)(t - 0.5);
}

void qb_ikf_reset(qb_ikf_t *f)
{
    memset(f, 0, sizeof *f);
    f->qw = (int32_t)1 << QB;
    f->pgg = P_GG0;
    f->pdd = DRIFT_INIT;
    f->al[2] = G0_IO;
}

/* q (x) (cos h, sin h * axis) for the half-angle vector h (Q.quat), by the 4th-order series */
static void rotate(const qb_ikf_t *f, int32_t hx, int32_t hy, int32_t hz, int32_t out[4])
{
    const int64_t one = (int64_t)1 << QB;
    int64_t h2 = (int64_t)mul(hx, hx, QB) + mul(hy, hy, QB) + mul(hz, hz, QB), h4, c, s;
    int32_t dx, dy, dz, w = f->qw, x = f->qx, y = f->qy, z = f->qz;
    if (h2 > one >> 4) { /* a half step over 0.25 rad: beyond the series; clip it */
        int32_t k = qdiv(one >> 2, qsqrt(h2, QB), QB);
        hx = mul(hx, k, QB);
        hy = mul(hy, k, QB);
        hz = mul(hz, k, QB);
        h2 = one >> 4;
    }
    h4 = mul64(h2, h2, QB);
    /* h2, h4 >= 0: unsigned divisions (the M0 then links no signed 64-bit divide) */
    c = one - (h2 >> 1) + (int64_t)((uint64_t)h4 / 24u);
    s = one - (int64_t)((uint64_t)h2 / 6u) + (int64_t)((uint64_t)h4 / 120u); /* sin(h) / h */
    dx = mul64(hx, s, QB);
    dy = mul64(hy, s, QB);
    dz = mul64(hz, s, QB);
    out[0] = sat((int64_t)mul64(w, c, QB) - mul(x, dx, QB) - mul(y, dy, QB) - mul(z, dz, QB));
    out[1] = sat((int64_t)mul(w, dx, QB) + mul64(x, c, QB) + mul(y, dz, QB) - mul(z, dy, QB));
    out[2] = sat((int64_t)mul(w, dy, QB) - mul(x, dz, QB) + mul64(y, c, QB) + mul(z, dx, QB));
    out[3] = sat((int64_t)mul(w, dz, QB) + mul(x, dy, QB) - mul(y, dx, QB) + mul64(z, c, QB));
}

void qb_ikf_quaternion(const qb_ikf_t *f, qb_real q[4])
{
    const qb_real s = 1.0 / (qb_real)((int32_t)1 << QB);
    int32_t p[4];
    if (f->rx == 0 && f->ry == 0 && f->rz == 0) {
        p[0] = f->qw;
        p[1] = f->qx;
        p[2] = f->qy;
        p[3] = f->qz;
    } else {
        const int sh = BB + DT - QB;
        rotate(f, mul(f->rx, LAT_HALF, sh), mul(f->ry, LAT_HALF, sh), mul(f->rz, LAT_HALF, sh), p);
    }
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

static void start(qb_ikf_t *f, const int32_t g[3], const int32_t a[3])
{
    const int64_t one = (int64_t)1 << QB;
    int32_t n = qsqrt((int64_t)mul(a[0], a[0], IO) + mul(a[1], a[1], IO) + mul(a[2], a[2], IO), IO), ux, uy, uz;
    int i;
    if (n < ((int32_t)1 << IO) / 2)
        return;
    ux = qdiv(a[0], n, QB);
    uy = qdiv(a[1], n, QB);
    uz = qdiv(a[2], n, QB);
    if (uz <= -one + 2) {
        f->qw = 0;
        f->qx = (int32_t)one;
        f->qy = f->qz = 0;
    } else {
        int32_t cw = qsqrt((one >> 1) + (uz >> 1), QB);
        f->qw = cw;
        f->qx = qdiv(uy, cw, QB - 1);
        f->qy = sat(-(int64_t)qdiv(ux, cw, QB - 1));
        f->qz = 0;
    }
    for (i = 0; i < 3; i++) {
        f->gl[i] = sat((int64_t)g[i] * ((int64_t)1 << (BB - IO)));
        f->al[i] = a[i];
    }
    f->started = 1;
}

/* Step 1: rest detection and the bias at rest (gyro in Q.bias, accelerometer in Q.io) */
static void rest(qb_ikf_t *f, const int32_t g[3], const int32_t a[3])
{
    int64_t dg = 0, da = 0;
    int i, inside = 1;
    for (i = 0; i < 3; i++)
        f->gl[i] = sat((int64_t)f->gl[i] + mul64(f->krq, (int64_t)g[i] - f->gl[i], CB));
    for (i = 0; i < 3; i++)
        f->al[i] = sat((int64_t)f->al[i] + mul64(f->krq, (int64_t)a[i] - f->al[i], CB));
    for (i = 0; i < 3; i++) {
        dg += mul64((int64_t)g[i] - f->gl[i], (int64_t)g[i] - f->gl[i], 16);
        da += mul64((int64_t)a[i] - f->al[i], (int64_t)a[i] - f->al[i], IO);
        inside = inside && -BIAS_MAX < f->gl[i] && f->gl[i] < BIAS_MAX;
    }
    if (sat(dg) < REST_G2 && sat(da) < REST_A2 && inside) /* held at REST_TIME_Q: it only has to reach it */
        f->rest_t = f->rest_t + f->dtq < REST_TIME_Q ? f->rest_t + f->dtq : REST_TIME_Q;
    else
        f->rest_t = 0;
    f->at_rest = f->rest_t >= REST_TIME_Q;
    if (f->at_rest) {
        f->bx = sat((int64_t)f->bx + mul64(f->kbq, (int64_t)f->gl[0] - f->bx, CB));
        f->by = sat((int64_t)f->by + mul64(f->kbq, (int64_t)f->gl[1] - f->by, CB));
        f->bz = sat((int64_t)f->bz + mul64(f->kbq, (int64_t)f->gl[2] - f->bz, CB));
    }
}

/* Step 3: the Kalman filter on (V, G_h, D); returns G_h (Q.vel) */
static void gravity(qb_ikf_t *f, int32_t fx, int32_t fy, int32_t rate, int32_t gh[2])
{
    const int sd = DT;
    int32_t dtq = f->dtq, dt2q = f->dt2q;
    int32_t e = mul(rate, dtq, IO + DT - CB);
    int32_t vx = sat((int64_t)f->vx + mul(fx, dtq, IO + DT - VB));
    int32_t vy = sat((int64_t)f->vy + mul(fy, dtq, IO + DT - VB));
    int32_t gxh = mul(f->dx, e, DB + CB - VB), gyh = mul(f->dy, e, DB + CB - VB);
    int32_t a_vv = sat((int64_t)f->pvv - 2 * (int64_t)mul(f->pvg, dtq, sd) + mul(f->pgg, dt2q, sd));
    int32_t a_vg = sat((int64_t)f->pvg + mul(e, f->pvd, CB) - mul(f->pgg, dtq, sd) -
                       mul(mul(e, f->pgd, CB), dtq, sd));
    int32_t a_vd = sat((int64_t)f->pvd - mul(f->pgd, dtq, sd));
    int32_t q_dt = mul(Q_G0, dtq, QG_SHIFT + sd);
    int32_t noise = sat((int64_t)q_dt + mul(mul(q_dt, K_ROT, IO), rate, IO));
    int32_t a_gg = sat((int64_t)f->pgg + 2 * (int64_t)mul(e, f->pgd, CB) + mul(mul(e, e, CB), f->pdd, CB) + noise);
    int32_t a_gd = sat((int64_t)f->pgd + mul(e, f->pdd, CB));
    int32_t a_dd = sat((int64_t)f->pdd + mul(DRIFT_NOISE, e, CB + 16));
    int32_t r = f->at_rest ? REST_R : (int32_t)1 << CB;
    int32_t den = sat((int64_t)mul(a_vv, dtq, sd) + r);
    int32_t kv = qdiv(mul(a_vv, dtq, sd), den, CB), kg = qdiv(mul(a_vg, dtq, sd), den, CB);
    int32_t kd = qdiv(mul(a_vd, dtq, sd), den, CB);
    gh[0] = sat((int64_t)gxh - mul(kg, vx, CB));
    gh[1] = sat((int64_t)gyh - mul(kg, vy, CB));
    f->dx = sat((int64_t)f->dx - mul(kd, vx, CB + VB - DB));
    f->dy = sat((int64_t)f->dy - mul(kd, vy, CB + VB - DB));
    f->vx = sat((int64_t)vx - mul(kv, vx, CB));
    f->vy = sat((int64_t)vy - mul(kv, vy, CB));
    f->pvv = sat((int64_t)a_vv - mul(kv, a_vv, CB));
    f->pvg = sat((int64_t)a_vg - mul(kv, a_vg, CB));
    f->pvd = sat((int64_t)a_vd - mul(kv, a_vd, CB));
    f->pgg = sat((int64_t)a_gg - mul(kg, a_vg, CB));
    f->pgd = sat((int64_t)a_gd - mul(kg, a_vd, CB));
    f->pdd = sat((int64_t)a_dd - mul(kd, a_vd, CB));
}

/* Step 4: the swing that makes (gxh, gyh, g0) vertical, applied to q, which is then normalised and kept */
static void rebase(qb_ikf_t *f, const int32_t q[4], const int32_t gh[2])
{
    const int64_t one = (int64_t)1 << QB;
    int32_t ux = mul(gh[0], INV_G0, VB), uy = mul(gh[1], INV_G0, VB), uz, cw, cx, cy, w, x, y, z, k;
    int64_t uh2 = (int64_t)mul(ux, ux, QB) + mul(uy, uy, QB), n2;
    if (uh2 > (81 * one) / 100) { /* at most a 64 degree step */
        k = qdiv(9 * one / 10, qsqrt(uh2, QB), QB);
        ux = mul(ux, k, QB);
        uy = mul(uy, k, QB);
        uh2 = (81 * one) / 100;
    }
    uz = qsqrt(one - uh2, QB);
    cw = qsqrt((one >> 1) + (uz >> 1), QB);
    cx = qdiv(uy, cw, QB - 1);
    cy = sat(-(int64_t)qdiv(ux, cw, QB - 1));
    w = sat((int64_t)mul(cw, q[0], QB) - mul(cx, q[1], QB) - mul(cy, q[2], QB));
    x = sat((int64_t)mul(cw, q[1], QB) + mul(cx, q[0], QB) + mul(cy, q[3], QB));
    y = sat((int64_t)mul(cw, q[2], QB) - mul(cx, q[3], QB) + mul(cy, q[0], QB));
    z = sat((int64_t)mul(cw, q[3], QB) + mul(cx, q[2], QB) - mul(cy, q[1], QB));
    n2 = (int64_t)mul(w, w, QB) + mul(x, x, QB) + mul(y, y, QB) + mul(z, z, QB);
    if (one >> 1 < n2 && n2 < one + (one >> 1)) {
        k = (int32_t)((3 * one - n2) >> 1); /* one Newton step of 1/sqrt(n2) from 1 */
    } else if (n2 > 0) {
        k = qdiv(one, qsqrt(n2, QB), QB);
    } else {
        k = (int32_t)one;
        w = (int32_t)one;
        x = y = z = 0;
    }
    f->qw = mul(w, k, QB);
    f->qx = mul(x, k, QB);
    f->qy = mul(y, k, QB);
    f->qz = mul(z, k, QB);
}

static void set_dt(qb_ikf_t *f, qb_real dt)
{
    if (f->dt_set && f->dt_cached == dt)
        return;
    f->dt_cached = dt;
    f->dt_set = 1;
    f->dtq = to_q(dt, DT);
    f->dt2q = to_q(dt * dt, DT);
    f->dthq = to_q(0.5 * dt, DT);
    f->krq = to_q(dt / (REST_TAU + dt), CB);
    f->kbq = to_q(dt / (REST_BIAS_TAU + dt), CB);
}

void qb_ikf_update(qb_ikf_t *f, qb_real gx, qb_real gy, qb_real gz, qb_real ax, qb_real ay, qb_real az, qb_real dt)
{
    int32_t g[3], a[3], q[4], r00, r01, r02, r10, r11, r12, fx, fy, rate, gh[2], wx, wy, wz;
    const int sh = BB + DT - QB;
    int i;
    if (!(dt > 0.0) || !isfinite(gx + gy + gz + ax + ay + az + dt))
        return;
    a[0] = to_q(ax, IO);
    a[1] = to_q(ay, IO);
    a[2] = to_q(az, IO);
    g[0] = to_q(gx, IO);
    g[1] = to_q(gy, IO);
    g[2] = to_q(gz, IO);
    if (!f->started) {
        start(f, g, a);
        return;
    }
    set_dt(f, dt);
    for (i = 0; i < 3; i++)
        g[i] = sat((int64_t)g[i] * ((int64_t)1 << (BB - IO))); /* Q8.24 holds 128 rad/s */
    rest(f, g, a);
    wx = g[0] - f->bx;
    wy = g[1] - f->by;
    wz = g[2] - f->bz;
    f->rx = wx;
    f->ry = wy;
    f->rz = wz;
    rotate(f, mul(wx, f->dthq, sh), mul(wy, f->dthq, sh), mul(wz, f->dthq, sh), q);
    rate = qsqrt(sat((int64_t)mul(wx, wx, 2 * BB - IO) + mul(wy, wy, 2 * BB - IO) + mul(wz, wz, 2 * BB - IO)), IO);
    r00 = (int32_t)(((int64_t)1 << QB) - 2 * ((int64_t)mul(q[2], q[2], QB) + mul(q[3], q[3], QB)));
    r01 = (int32_t)(2 * ((int64_t)mul(q[1], q[2], QB) - mul(q[0], q[3], QB)));
    r02 = (int32_t)(2 * ((int64_t)mul(q[1], q[3], QB) + mul(q[0], q[2], QB)));
    r10 = (int32_t)(2 * ((int64_t)mul(q[1], q[2], QB) + mul(q[0], q[3], QB)));
    r11 = (int32_t)(((int64_t)1 << QB) - 2 * ((int64_t)mul(q[1], q[1], QB) + mul(q[3], q[3], QB)));
    r12 = (int32_t)(2 * ((int64_t)mul(q[2], q[3], QB) - mul(q[0], q[1], QB)));
    fx = sat((int64_t)mul(r00, a[0], QB) + mul(r01, a[1], QB) + mul(r02, a[2], QB));
    fy = sat((int64_t)mul(r10, a[0], QB) + mul(r11, a[1], QB) + mul(r12, a[2], QB));
    gravity(f, fx, fy, rate, gh);
    rebase(f, q, gh);
    f->bx = f->bx > BIAS_MAX ? BIAS_MAX : f->bx < -BIAS_MAX ? -BIAS_MAX : f->bx;
    f->by = f->by > BIAS_MAX ? BIAS_MAX : f->by < -BIAS_MAX ? -BIAS_MAX : f->by;
    f->bz = f->bz > BIAS_MAX ? BIAS_MAX : f->bz < -BIAS_MAX ? -BIAS_MAX : f->bz;
}
