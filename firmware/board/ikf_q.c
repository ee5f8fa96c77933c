/* ikf in fixed point: step for step fcb_sim/estimation/ikf_fixed.py (ikf_q.h says what and why). Python's
 * integers do not overflow: where its sums are not saturated, these are int64, and a product of two numbers
 * wider than 32 bits takes the 128-bit path of ikfq_mul, so the bits agree on every input. */
#include "ikf_q.h"

#include <math.h>

#define I32_MAX INT32_C(0x7FFFFFFF)
#define I32_MIN (-INT32_C(0x7FFFFFFF) - 1)
#define G0 9.81
#define P_GG0 0.1
#define REST_T_CAP (INT64_C(1) << 62)

/* FMT(s): the filter's formats. Built with -DIKFQ_DEFAULT_FORMATS (the C board) they are ikf_fixed.Formats()'s
 * at compile time, whatever the set-up was given: every shift is then an immediate (0.4 KB less on the Cortex-M0). */
/* LITE(s): the variant that fits the Cortex-M0 (ikfq_set_lite). Built with -DIKFQ_LITE_ONLY (the C board, which
 * runs it alone) the exact twin's paths fold away: 2 KB less flash. */
#ifdef IKFQ_LITE_ONLY
#define LITE(s) 1
#else
#define LITE(s) ((s)->lite)
#endif

#ifdef IKFQ_DEFAULT_FORMATS
static const ikfq_formats_t DEFAULT_FORMATS = {16, 30, 30, 24, 24, 28, 30};
#define FMT(s) DEFAULT_FORMATS
#else
#define FMT(s) ((s)->f)
#endif

static int32_t sat(int64_t v)
{
    return v > I32_MAX ? I32_MAX : v < I32_MIN ? I32_MIN : (int32_t)v;
}

/* v << up saturated, in 32-bit operations (a 64-bit product is a libgcc call on the M0) */
static int32_t shl_sat(int32_t v, int up)
{
    if (v > (I32_MAX >> up))
        return I32_MAX;
    if (v < (I32_MIN >> up))
        return I32_MIN;
    return (int32_t)((uint32_t)v << up);
}

static uint64_t mag(int64_t v)
{
    return v < 0 ? 0u - (uint64_t)v : (uint64_t)v;
}

/* sign * ((|a b| + 2^(shift-1)) >> shift), saturated: Python's rounding for either sign. */
static int32_t mul_wide(int64_t a, int64_t b, unsigned shift)
{
    uint64_t ua = mag(a), ub = mag(b);
    uint64_t a0 = ua & 0xFFFFFFFFu, a1 = ua >> 32, b0 = ub & 0xFFFFFFFFu, b1 = ub >> 32;
    uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0;
    uint64_t mid = (p00 >> 32) + (p01 & 0xFFFFFFFFu) + (p10 & 0xFFFFFFFFu);
    uint64_t lo = (p00 & 0xFFFFFFFFu) | (mid << 32);
    uint64_t hi = a1 * b1 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
    uint64_t h = (uint64_t)1 << (shift - 1), rlo, rhi;
    int neg = (a < 0) != (b < 0);
    lo += h;
    hi += lo < h;
    rlo = shift < 64 ? (lo >> shift) | (hi << (64 - shift)) : hi >> (shift - 64);
    rhi = shift < 64 ? hi >> shift : 0;
    if (neg)
        return rhi || rlo > UINT64_C(0x80000000) ? I32_MIN : (int32_t)(0 - (int64_t)rlo);
    return rhi || rlo > UINT64_C(0x7FFFFFFF) ? I32_MAX : (int32_t)rlo;
}

/* The same for two int32 in 32-bit operations only: the Cortex-M0 has a 32x32->32 MULS and no 64-bit product,
 * so the signed 64-bit product from four 16x16 products (libfixmath's fix16_mul without 64-bit types), then
 * (p + h - (p < 0)) >> shift, which is Python's rounding half away from zero for either sign. */
static int32_t mul32(int32_t a, int32_t b, unsigned shift)
{
    int32_t ah = a >> 16, bh = b >> 16, hi;
    uint32_t al = (uint32_t)a & 0xFFFFu, bl = (uint32_t)b & 0xFFFFu, lo, add;
    int32_t cross = ah * (int32_t)bl; /* |cross| < 2^31: each is a 16-bit signed times a 16-bit unsigned */
    int32_t cross2 = bh * (int32_t)al;
    uint32_t ll = al * bl, t;
    hi = ah * bh + (cross >> 16) + (cross2 >> 16);
    t = ll + ((uint32_t)cross << 16);
    hi += t < ll;
    lo = t + ((uint32_t)cross2 << 16);
    hi += lo < t;
    /* + h - (p < 0), a 64-bit addition of a non-negative number below 2^45 */
    if (shift <= 32) {
        add = (UINT32_C(1) << (shift - 1)) - (uint32_t)(hi < 0);
        lo += add;
        hi += lo < add;
    } else {
        uint32_t l0 = lo;
        lo -= (uint32_t)(hi < 0);
        hi += (int32_t)(UINT32_C(1) << (shift - 33)) - (lo > l0);
    }
    if (shift < 32) {
        int32_t rhi = hi >> shift;
        uint32_t rlo = (lo >> shift) | ((uint32_t)hi << (32 - shift));
        if (rhi != ((int32_t)rlo >> 31))
            return hi < 0 ? I32_MIN : I32_MAX;
        return (int32_t)rlo;
    } else {
        int32_t r = hi >> (shift - 32); /* fits: the 64-bit value >> 32 or more, from a 62-bit product */
        return r;
    }
}

int32_t ikfq_mul(int64_t a, int64_t b, unsigned shift)
{
    if ((int32_t)a == a && (int32_t)b == b)
        return mul32((int32_t)a, (int32_t)b, shift);
    return mul_wide(a, b, shift);
}

/* Most products are of two int32: straight to mul32 (three arguments in registers, no 64-bit test). */
#define MUL(a, b, shift) mul32((a), (b), (shift))

int32_t ikfq_div(int64_t a, int64_t b, unsigned shift)
{
    uint64_t n, d, r;
    if (b == 0)
        return a >= 0 ? I32_MAX : I32_MIN;
    n = mag(a) << shift;
    d = mag(b);
    r = (2 * n + d) / (2 * d);
    if ((a < 0) != (b < 0))
        return r > UINT64_C(0x80000000) ? I32_MIN : (int32_t)(0 - (int64_t)r);
    return r > UINT64_C(0x7FFFFFFF) ? I32_MAX : (int32_t)r;
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

int64_t ikfq_sqrt(int64_t a, unsigned frac)
{
    uint64_t n, r;
    if (a <= 0)
        return 0;
    n = (uint64_t)a << frac;
    r = isqrt64(n);
    return (int64_t)(n - r * r > r ? r + 1 : r);
}

int32_t ikfq_to_q(double x, unsigned frac)
{
    double t = x * ldexp(1.0, (int)frac);
    if (t >= 0.0) {
        double u = t + 0.5;
        return u >= 2147483648.0 ? I32_MAX : (int32_t)u;
    } else {
        double u = t - 0.5;
        return u <= -2147483649.0 ? I32_MIN : sat((int64_t)u);
    }
}

static int64_t to_q_wide(double x, unsigned frac)
{
    double u = x * ldexp(1.0, (int)frac) + 0.5;
    return u >= 4.6e18 ? REST_T_CAP : (int64_t)u; /* a non-negative time */
}

void ikfq_default_formats(ikfq_formats_t *f)
{
    f->io = 16;
    f->dt = 30;
    f->quat = 30;
    f->bias = 24;
    f->vel = 24;
    f->drift = 28;
    f->cov = 30;
}

void ikfq_default_params(ikfq_params_t *p)
{
    double k = sqrt(2.0) / 4.5;
    p->q_g0 = pow(k, 4.0);
    p->k_rot = 0.5;
    p->drift_init = 1e-3;
    p->drift_noise = 1e-6;
    p->latency = 0.0025;
    p->rest_r = 0.01;
    p->rest_gyro = 2.0 * 3.14159265358979323846 / 180.0;
    p->rest_acc = 0.5;
    p->rest_time = 1.5;
    p->rest_tau = 0.5;
    p->rest_bias_tau = 2.0;
    p->bias_max = 5.0 * 3.14159265358979323846 / 180.0;
}

void ikfq_init(ikfq_t *s, const ikfq_formats_t *f, const ikfq_params_t *p)
{
    int sh;
    s->f = *f;
    /* q_g0 is ~0.01: up to 5 more fractional bits while it fits */
    for (sh = 5; sh > -30; sh--)
        if (p->q_g0 * ldexp(1.0, f->cov + sh) < 2147483647.0)
            break;
    s->qg_shift = sh;
    s->q_g0 = ikfq_to_q(p->q_g0, (unsigned)(f->cov + sh));
    s->k_rot = ikfq_to_q(p->k_rot, f->io);
    s->drift_noise = ikfq_to_q(p->drift_noise, f->cov + 16u);
    s->rest_r = ikfq_to_q(p->rest_r, f->cov);
    s->rest_g2 = ikfq_to_q(p->rest_gyro * p->rest_gyro, 2u * f->bias - 16u);
    s->rest_a2 = ikfq_to_q(p->rest_acc * p->rest_acc, f->io);
    s->bias_max = ikfq_to_q(p->bias_max, f->bias);
    s->inv_g0 = ikfq_to_q(1.0 / G0, f->quat);
    s->lat_half = ikfq_to_q(0.5 * p->latency, f->dt);
    s->rest_time = to_q_wide(p->rest_time, f->dt);
    s->pgg0 = ikfq_to_q(P_GG0, f->cov);
    s->pdd0 = ikfq_to_q(p->drift_init, f->cov);
    s->g0_io = ikfq_to_q(G0, f->io);
    s->swing_max = (int32_t)((81 * (INT64_C(1) << f->quat)) / 100);
    s->swing_k = (int32_t)((9 * (INT64_C(1) << f->quat)) / 10);
    s->dt_last = 0.0;
    s->from_table = 0;
    s->dtq = s->dt2q = s->dthq = s->krq = s->kbq = 0;
    /* the rest filters' time constants live only in krq and kbq: keep them for ikfq_set_dt */
    s->rest_tau_ = p->rest_tau;
    s->rest_bias_tau_ = p->rest_bias_tau;
    s->decim = 1;
    s->lite = 0;
    ikfq_reset(s);
}

void ikfq_set_lite(ikfq_t *s, int32_t on)
{
    s->lite = on != 0;
    ikfq_reset(s);
}

void ikfq_set_decimation(ikfq_t *s, int32_t n)
{
    s->decim = n > 1 ? n : 1;
    s->dt_last = 0.0; /* the dt constants are of decim * dt: derive them again */
    ikfq_reset(s);
}

void ikfq_init_q(ikfq_t *s, const ikfq_formats_t *f, const ikfq_consts_t *c)
{
    s->f = *f;
    s->qg_shift = c->qg_shift;
    s->q_g0 = c->q_g0;
    s->k_rot = c->k_rot;
    s->drift_noise = c->drift_noise;
    s->rest_r = c->rest_r;
    s->rest_g2 = c->rest_g2;
    s->rest_a2 = c->rest_a2;
    s->bias_max = c->bias_max;
    s->inv_g0 = c->inv_g0;
    s->lat_half = c->lat_half;
    s->pgg0 = c->pgg0;
    s->pdd0 = c->pdd0;
    s->g0_io = c->g0_io;
    s->swing_max = c->swing_max;
    s->swing_k = c->swing_k;
    s->rest_time = c->rest_time;
    s->dtq = c->dtq;
    s->dt2q = c->dt2q;
    s->dthq = c->dthq;
    s->krq = c->krq;
    s->kbq = c->kbq;
    s->decim = c->decim > 1 ? c->decim : 1;
    s->lite = c->lite != 0;
    s->dt_last = 0.0; /* ikfq_update (host) would derive them again from its dt; ikfq_step keeps these */
    s->rest_tau_ = s->rest_bias_tau_ = 0.0;
    s->from_table = 1;
    ikfq_reset(s);
}

void ikfq_consts(const ikfq_t *s, ikfq_consts_t *c)
{
    c->qg_shift = s->qg_shift;
    c->q_g0 = s->q_g0;
    c->k_rot = s->k_rot;
    c->drift_noise = s->drift_noise;
    c->rest_r = s->rest_r;
    c->rest_g2 = s->rest_g2;
    c->rest_a2 = s->rest_a2;
    c->bias_max = s->bias_max;
    c->inv_g0 = s->inv_g0;
    c->lat_half = s->lat_half;
    c->pgg0 = s->pgg0;
    c->pdd0 = s->pdd0;
    c->g0_io = s->g0_io;
    c->swing_max = s->swing_max;
    c->swing_k = s->swing_k;
    c->rest_time = s->rest_time;
    c->dtq = s->dtq;
    c->dt2q = s->dt2q;
    c->dthq = s->dthq;
    c->krq = s->krq;
    c->kbq = s->kbq;
    c->decim = s->decim;
    c->lite = s->lite;
}

void ikfq_reset(ikfq_t *s)
{
    int i;
    s->qw = INT32_C(1) << FMT(s).quat;
    s->qx = s->qy = s->qz = 0;
    s->vx = s->vy = s->dx = s->dy = 0;
    s->pvv = s->pvg = s->pvd = s->pgd = 0;
    s->pgg = s->pgg0;
    s->pdd = s->pdd0;
    s->bx = s->by = s->bz = 0;
    s->rx = s->ry = s->rz = 0;
    for (i = 0; i < 3; i++)
        s->gl[i] = s->al[i] = 0;
    s->al[2] = s->g0_io;
    s->rest_t = 0;
    s->at_rest = 0;
    s->started = 0;
    s->phase = 0;
    s->fsum[0] = s->fsum[1] = s->fsum[2] = s->fsum[3] = s->rate = s->gxh = s->gyh = 0;
    s->qm[0] = INT32_C(1) << 30;
    s->qm[1] = s->qm[2] = s->qm[3] = 0;
}

void ikfq_set_dt(ikfq_t *s, double dt)
{
    const ikfq_formats_t *f = &FMT(s);
    double dn = s->decim * dt; /* the gravity part's step */
    if (dt == s->dt_last || s->from_table)
        return;
    s->dt_last = dt;
    s->dtq = ikfq_to_q(dn, f->dt);
    s->dt2q = ikfq_to_q(dn * dn, f->dt);
    s->dthq = ikfq_to_q(0.5 * dt, f->dt);
    s->krq = ikfq_to_q(dn / (s->rest_tau_ + dn), f->cov);
    s->kbq = ikfq_to_q(dn / (s->rest_bias_tau_ + dn), f->cov);
}

/* q (x) (cos h, sin h * axis) for the half-angle vector h (Q.quat), by the 4th-order series */
static void rotate(const ikfq_t *s, int64_t hx, int64_t hy, int64_t hz, int32_t out[4])
{
    unsigned qb = FMT(s).quat;
    int64_t one = INT64_C(1) << qb, h2, h4, c, sn, dx, dy, dz, w = s->qw, x = s->qx, y = s->qy, z = s->qz;
    h2 = (int64_t)MUL(hx, hx, qb) + MUL(hy, hy, qb) + MUL(hz, hz, qb);
    if (h2 > one >> 4) { /* a half step over 0.25 rad: beyond the series' 1e-6; clip it */
        int32_t k = ikfq_div(one >> 2, ikfq_sqrt(h2, qb), qb);
        hx = MUL(hx, k, qb);
        hy = MUL(hy, k, qb);
        hz = MUL(hz, k, qb);
        h2 = one >> 4;
    }
    h4 = MUL(h2, h2, qb); /* h2 <= one / 16 here: both fit 32 bits, so 32-bit divisions */
    c = one - (h2 >> 1) + (int32_t)h4 / 24;
    sn = one - (int32_t)h2 / 6 + (int32_t)h4 / 120; /* sin(h) / h */
    dx = MUL(hx, sn, qb);
    dy = MUL(hy, sn, qb);
    dz = MUL(hz, sn, qb);
    out[0] = sat((int64_t)MUL(w, c, qb) - MUL(x, dx, qb) - MUL(y, dy, qb) - MUL(z, dz, qb));
    out[1] = sat((int64_t)MUL(w, dx, qb) + MUL(x, c, qb) + MUL(y, dz, qb) - MUL(z, dy, qb));
    out[2] = sat((int64_t)MUL(w, dy, qb) - MUL(x, dz, qb) + MUL(y, c, qb) + MUL(z, dx, qb));
    out[3] = sat((int64_t)MUL(w, dz, qb) + MUL(x, dy, qb) - MUL(y, dx, qb) + MUL(z, c, qb));
}

static void rotate_lite(const ikfq_t *s, int32_t hx, int32_t hy, int32_t hz, int32_t out[4]);
static void half_step(const int64_t w[3], int32_t k, int32_t h[3]);

void ikfq_predicted(const ikfq_t *s, int32_t q[4])
{
    unsigned sh = FMT(s).bias + FMT(s).dt - FMT(s).quat;
    int64_t lat = s->lat_half;
    if (lat == 0 || (s->rx == 0 && s->ry == 0 && s->rz == 0)) {
        q[0] = s->qw;
        q[1] = s->qx;
        q[2] = s->qy;
        q[3] = s->qz;
        return;
    }
    if (LITE(s)) {
        const int64_t w[3] = {s->rx, s->ry, s->rz};
        int32_t h[3];
        half_step(w, s->lat_half, h);
        rotate_lite(s, h[0], h[1], h[2], q);
    } else
        rotate(s, ikfq_mul(s->rx, lat, sh), ikfq_mul(s->ry, lat, sh), ikfq_mul(s->rz, lat, sh), q);
}

static int32_t clamp(int32_t v, int32_t m)
{
    return v > m ? m : v < -m ? -m : v;
}

/* y + k (x - y), saturated: a step of the rest low-passes and of the bias at rest */
static int32_t lowpass(int32_t y, int64_t x, int32_t k, unsigned cb)
{
    return sat(y + (int64_t)ikfq_mul(k, x - y, cb));
}

/* Step 1: rest detection and the bias at rest (gyro g in Q.bias, accelerometer a in Q.io) */
static void rest(ikfq_t *s, const int32_t g[3], const int32_t a[3])
{
    unsigned io = FMT(s).io, cb = FMT(s).cov;
    int64_t dg = 0, da = 0;
    int32_t m = s->bias_max, *b[3];
    int i, inside = 1;
    b[0] = &s->bx;
    b[1] = &s->by;
    b[2] = &s->bz;
    for (i = 0; i < 3; i++) {
        int64_t d, e;
        s->gl[i] = lowpass(s->gl[i], g[i], s->krq, cb);
        s->al[i] = lowpass(s->al[i], a[i], s->krq, cb);
        d = (int64_t)g[i] - s->gl[i];
        e = (int64_t)a[i] - s->al[i];
        dg += ikfq_mul(d, d, 16);
        da += ikfq_mul(e, e, io);
        inside = inside && -m < s->gl[i] && s->gl[i] < m;
    }
    if (sat(dg) < s->rest_g2 && sat(da) < s->rest_a2 && inside)
        s->rest_t = s->rest_t + s->dtq < s->rest_time ? s->rest_t + s->dtq : s->rest_time;
    else
        s->rest_t = 0;
    s->at_rest = s->rest_t >= s->rest_time;
    for (i = 0; i < 3 && s->at_rest; i++)
        *b[i] = lowpass(*b[i], s->gl[i], s->kbq, cb);
}

/* Step 3: the Kalman filter on (V, G_h, D), fed the horizontal specific force's integral over the step (dvx, dvy,
 * Q.vel) and the turn rate (Q.io). In two halves a spread filter runs apart (ikf_lite.py): the prediction leaves
 * V, G_h and the covariance in the state. */
static void predict(ikfq_t *s, int32_t dvx, int32_t dvy, int64_t rate)
{
    unsigned io = FMT(s).io, vb = FMT(s).vel, db = FMT(s).drift, cb = FMT(s).cov, sd = FMT(s).dt;
    int64_t dtq = s->dtq, dt2q = s->dt2q;
    int32_t e = ikfq_mul(rate, dtq, io + sd - cb);
    int32_t pvv = s->pvv, pvg = s->pvg, pvd = s->pvd, pgg = s->pgg, pgd = s->pgd, pdd = s->pdd, q_dt, noise;
    s->vx = sat(s->vx + (int64_t)dvx);
    s->vy = sat(s->vy + (int64_t)dvy);
    s->gxh = MUL(s->dx, e, db + cb - vb);
    s->gyh = MUL(s->dy, e, db + cb - vb);
    s->pvv = sat(pvv - 2 * (int64_t)MUL(pvg, dtq, sd) + MUL(pgg, dt2q, sd));
    s->pvg = sat((int64_t)pvg + MUL(e, pvd, cb) - MUL(pgg, dtq, sd) - MUL(MUL(e, pgd, cb), dtq, sd));
    s->pvd = sat(pvd - (int64_t)MUL(pgd, dtq, sd));
    q_dt = MUL(s->q_g0, dtq, (unsigned)(s->qg_shift + (int32_t)sd));
    noise = sat(q_dt + (int64_t)ikfq_mul(MUL(q_dt, s->k_rot, io), rate, io));
    s->pgg = sat(pgg + 2 * (int64_t)MUL(e, pgd, cb) + MUL(MUL(e, e, cb), pdd, cb) + noise);
    s->pgd = sat(pgd + (int64_t)MUL(e, pdd, cb));
    s->pdd = sat(pdd + (int64_t)MUL(s->drift_noise, e, cb + 16u));
}

/* ... and the update with the pseudo measurement V = 0 on the predicted state; G_h (Q.vel) left in gxh, gyh */
static void correct(ikfq_t *s)
{
    unsigned vb = FMT(s).vel, db = FMT(s).drift, cb = FMT(s).cov, sd = FMT(s).dt;
    int64_t dtq = s->dtq;
    int32_t vx = s->vx, vy = s->vy, a_vv = s->pvv, a_vg = s->pvg, a_vd = s->pvd, a_gg = s->pgg, a_gd = s->pgd;
    int32_t a_dd = s->pdd, r, den, kv, kg, kd;
    r = s->at_rest ? s->rest_r : (int32_t)(INT32_C(1) << cb);
    den = sat((int64_t)MUL(a_vv, dtq, sd) + r);
    if (LITE(s)) { /* one division: 1 / den in Q8.24 (den >= rest_r), then three products */
        int32_t inv = ikfq_div(INT64_C(1) << cb, den, 24);
        kv = MUL(MUL(a_vv, dtq, sd), inv, 24);
        kg = MUL(MUL(a_vg, dtq, sd), inv, 24);
        kd = MUL(MUL(a_vd, dtq, sd), inv, 24);
    } else {
        kv = ikfq_div(MUL(a_vv, dtq, sd), den, cb);
        kg = ikfq_div(MUL(a_vg, dtq, sd), den, cb);
        kd = ikfq_div(MUL(a_vd, dtq, sd), den, cb);
    }
    s->gxh = sat(s->gxh - (int64_t)MUL(kg, vx, cb));
    s->gyh = sat(s->gyh - (int64_t)MUL(kg, vy, cb));
    s->dx = sat(s->dx - (int64_t)MUL(kd, vx, cb + vb - db));
    s->dy = sat(s->dy - (int64_t)MUL(kd, vy, cb + vb - db));
    s->vx = sat(vx - (int64_t)MUL(kv, vx, cb));
    s->vy = sat(vy - (int64_t)MUL(kv, vy, cb));
    s->pvv = sat(a_vv - (int64_t)MUL(kv, a_vv, cb));
    s->pvg = sat(a_vg - (int64_t)MUL(kv, a_vg, cb));
    s->pvd = sat(a_vd - (int64_t)MUL(kv, a_vd, cb));
    s->pgg = sat(a_gg - (int64_t)MUL(kg, a_vg, cb));
    s->pgd = sat(a_gd - (int64_t)MUL(kg, a_vd, cb));
    s->pdd = sat(a_dd - (int64_t)MUL(kd, a_vd, cb));
}

/* Step 4: the swing that makes (gxh, gyh, g0) vertical, applied to q, normalised by one Newton step, kept */
static void rebase(ikfq_t *s, const int32_t q[4], int32_t gxh, int32_t gyh)
{
    unsigned qb = FMT(s).quat, vb = FMT(s).vel;
    int64_t one = INT64_C(1) << qb, ux, uy, uh2, uz, cw, cx, cy, n2, k, w, x, y, z;
    ux = MUL(gxh, s->inv_g0, vb);
    uy = MUL(gyh, s->inv_g0, vb);
    uh2 = (int64_t)MUL(ux, ux, qb) + MUL(uy, uy, qb);
    if (uh2 > s->swing_max) { /* at most a 64 degree step */
        int32_t kk = ikfq_div(s->swing_k, ikfq_sqrt(uh2, qb), qb);
        ux = MUL(ux, kk, qb);
        uy = MUL(uy, kk, qb);
        uh2 = s->swing_max;
    }
    uz = ikfq_sqrt(one - uh2, qb);
    cw = ikfq_sqrt((one >> 1) + (uz >> 1), qb);
    cx = ikfq_div(uy, cw, qb - 1);
    cy = -(int64_t)ikfq_div(ux, cw, qb - 1);
    w = sat((int64_t)MUL(cw, q[0], qb) - MUL(cx, q[1], qb) - ikfq_mul(cy, q[2], qb));
    x = sat((int64_t)MUL(cw, q[1], qb) + MUL(cx, q[0], qb) + ikfq_mul(cy, q[3], qb));
    y = sat((int64_t)MUL(cw, q[2], qb) - MUL(cx, q[3], qb) + ikfq_mul(cy, q[0], qb));
    z = sat((int64_t)MUL(cw, q[3], qb) + MUL(cx, q[2], qb) - ikfq_mul(cy, q[1], qb));
    n2 = (int64_t)MUL(w, w, qb) + MUL(x, x, qb) + MUL(y, y, qb) + MUL(z, z, qb);
    if (one >> 1 < n2 && n2 < one + (one >> 1)) {
        k = (3 * one - n2) >> 1;
    } else if (n2 > 0) { /* never in use: a full normalisation */
        k = ikfq_div(one, ikfq_sqrt(n2, qb), qb);
    } else {
        k = one;
        w = one;
        x = y = z = 0;
    }
    s->qw = MUL(w, k, qb);
    s->qx = MUL(x, k, qb);
    s->qy = MUL(y, k, qb);
    s->qz = MUL(z, k, qb);
}

/* --- the variant cut to fit the Cortex-M0 (fcb_sim/estimation/ikf_lite.py says what and why) ------------------ */

#define ONE30 (INT32_C(1) << 30)
#define R28 (INT32_C(1) << 28)
#define R30 (INT64_C(1) << 30)
#define R27 (INT32_C(1) << 27)
#define SIXTH_Q30 INT32_C(178956971)
#define C24_Q30 INT32_C(44739243) /* 2^30 / 24 */
#define C120_Q30 INT32_C(8947849) /* 2^30 / 120 */
#define PIECES 4

/* (a b) >> 30 of two Q2.30 from three 16x16 MULS, the low halves' product dropped, wrapped as ikf_lite.qmul */
static inline __attribute__((always_inline)) int32_t qmul(int32_t a, int32_t b)
{
    int32_t ah = a >> 16, bh = b >> 16;
    int32_t al = (int32_t)((uint32_t)a & 0xFFFFu), bl = (int32_t)((uint32_t)b & 0xFFFFu);
    return (int32_t)((uint32_t)(ah * bh) * 4u + (uint32_t)((ah * bl) >> 14) + (uint32_t)((al * bh) >> 14));
}

/* The same as a call: the gravity part's pieces (once in decim samples) take it, 1.5 KB less flash than inlined */
static __attribute__((noinline)) int32_t qmulf(int32_t a, int32_t b)
{
    return qmul(a, b);
}

uint32_t ikfq_isqrt32(uint32_t n) /* floor; ctl_q.c's angles use it too */
{
    uint32_t r = 0, bit = UINT32_C(1) << 30;
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

/* The half-step vector w k >> 24 (Q2.30 from a Q8.24 rate and a Q2.30 half step k): qmul(w, k << 6) while k is
 * below 2^24 (dt under 31 ms) and |w| below 2^30 (64 rad/s), else the exact product */
static void half_step(const int64_t w[3], int32_t k, int32_t h[3])
{
    int i;
    if (k < (INT32_C(1) << 24) && -R30 < w[0] && w[0] < R30 && -R30 < w[1] && w[1] < R30 && -R30 < w[2] && w[2] < R30) {
        for (i = 0; i < 3; i++)
            h[i] = qmul((int32_t)w[i], k << 6);
    } else {
        for (i = 0; i < 3; i++)
            h[i] = ikfq_mul(w[i], k, 24);
    }
}

/* a (x) b, each term a qmul, the sums in 32 bits (wrapped, as ikf_lite.qprod: of unit quaternions and steps they
 * stay below 1.01 * 2^30): the strapdown's, the prediction's and the rebase's product, one copy of its 16 inlined
 * products (the board's flash goal) */
static __attribute__((noinline)) void qprod(const int32_t a[4], const int32_t b[4], int32_t out[4])
{
    out[0] = (int32_t)((uint32_t)qmul(a[0], b[0]) - (uint32_t)qmul(a[1], b[1]) - (uint32_t)qmul(a[2], b[2])
                       - (uint32_t)qmul(a[3], b[3]));
    out[1] = (int32_t)((uint32_t)qmul(a[0], b[1]) + (uint32_t)qmul(a[1], b[0]) + (uint32_t)qmul(a[2], b[3])
                       - (uint32_t)qmul(a[3], b[2]));
    out[2] = (int32_t)((uint32_t)qmul(a[0], b[2]) - (uint32_t)qmul(a[1], b[3]) + (uint32_t)qmul(a[2], b[0])
                       + (uint32_t)qmul(a[3], b[1]));
    out[3] = (int32_t)((uint32_t)qmul(a[0], b[3]) + (uint32_t)qmul(a[1], b[2]) - (uint32_t)qmul(a[2], b[1])
                       + (uint32_t)qmul(a[3], b[0]));
}

/* q (x) (cos h, sin h * axis) by the 2nd-order series; a half step over 0.25 rad is clipped as rotate() does */
static void rotate_lite(const ikfq_t *s, int32_t hx, int32_t hy, int32_t hz, int32_t out[4])
{
    const int32_t q[4] = {s->qw, s->qx, s->qy, s->qz};
    int32_t h2, sn, r[4];
    if (-R28 < hx && hx < R28 && -R28 < hy && hy < R28 && -R28 < hz && hz < R28)
        h2 = qmulf(hx, hx) + qmulf(hy, hy) + qmulf(hz, hz);
    else
        h2 = ONE30;
    if (h2 > ONE30 >> 4) {
        int64_t e2 = (int64_t)MUL(hx, hx, 30) + MUL(hy, hy, 30) + MUL(hz, hz, 30);
        int32_t k = ikfq_div(ONE30 >> 2, ikfq_sqrt(e2, 30), 30);
        hx = MUL(hx, k, 30);
        hy = MUL(hy, k, 30);
        hz = MUL(hz, k, 30);
        h2 = ONE30 >> 4;
    }
    r[0] = ONE30 - (h2 >> 1);
    sn = ONE30 - qmulf(h2, SIXTH_Q30);
    if (h2 > ONE30 >> 8) { /* a half step over 0.0625 rad (80 rad/s at 400 Hz, or a long dt): 4th order too */
        int32_t h4 = qmulf(h2, h2);
        r[0] += qmulf(h4, C24_Q30);
        sn += qmulf(h4, C120_Q30);
    }
    r[1] = qmulf(hx, sn);
    r[2] = qmulf(hy, sn);
    r[3] = qmulf(hz, sn);
    qprod(q, r, out);
}

/* The turn rate (a 32-bit root), and apart (the next piece) the horizontal specific force in the earth frame:
 * what the prediction takes */
static void rate_lite(ikfq_t *s, int64_t wx, int64_t wy, int64_t wz)
{
    unsigned io = FMT(s).io, bb = FMT(s).bias;
    int32_t r2 = sat((int64_t)ikfq_mul(wx, wx, 2 * bb - io) + ikfq_mul(wy, wy, 2 * bb - io)
                     + ikfq_mul(wz, wz, 2 * bb - io));
    s->rate = (int32_t)(ikfq_isqrt32((uint32_t)r2) << 8);
}

/* V plus the earth-frame horizontal specific force integrated over the decim samples: their body-frame sum (fsum)
 * turned by q at their middle (qm), by the product's one copy, q (x) (0, sum) (x) q*, times dt; the sum restarts
 * (ikf_lite.py's _force) */
static void force_lite(ikfq_t *s)
{
    int32_t q[4], p[4], e[4], i;
    unsigned sh = FMT(s).io + FMT(s).dt - FMT(s).vel - 1u; /* times dt = 2 dthq: Q.io * Q.dt -> Q.vel */
    qprod(s->qm, s->fsum, p);
    q[0] = s->qm[0];
    for (i = 1; i < 4; i++) { /* q*; the sum restarts */
        q[i] = (int32_t)(0u - (uint32_t)s->qm[i]);
        s->fsum[i] = 0;
    }
    qprod(p, q, e);
    s->vx = sat((int64_t)s->vx + MUL(e[1], s->dthq, sh));
    s->vy = sat((int64_t)s->vy + MUL(e[2], s->dthq, sh));
}

/* q turned by the 2nd-order swing (1 - |u|^2/8, uy/2, -ux/2, 0), then the Newton normalisation */
static void rebase_lite(ikfq_t *s)
{
    unsigned vb = FMT(s).vel;
    int32_t ux = clamp(MUL(s->gxh, s->inv_g0, vb), ONE30 - 1), uy = clamp(MUL(s->gyh, s->inv_g0, vb), ONE30 - 1);
    int32_t c[4], q[4] = {s->qw, s->qx, s->qy, s->qz}, o[4], w, x, y, z, k, passes;
    int64_t uh2 = (int64_t)qmulf(ux, ux) + qmulf(uy, uy), n2;
    if (uh2 > s->swing_max) { /* at most a 64 degree step (never in use) */
        int32_t kk = ikfq_div(s->swing_k, ikfq_sqrt(uh2, 30), 30);
        ux = MUL(ux, kk, 30);
        uy = MUL(uy, kk, 30);
        uh2 = s->swing_max;
    }
    c[0] = ONE30 - (int32_t)(uh2 >> 3);
    c[1] = uy >> 1;
    c[2] = -(ux >> 1);
    c[3] = 0;
    qprod(c, q, o); /* c (x) q: the swing in the earth frame */
    w = o[0];
    x = o[1];
    y = o[2];
    z = o[3];
    n2 = (int64_t)qmulf(w, w) + qmulf(x, x) + qmulf(y, y) + qmulf(z, z);
    if (n2 <= 0) { /* never in use: a lost attitude starts level */
        s->qw = ONE30;
        s->qx = s->qy = s->qz = 0;
        return;
    }
    /* Newton steps of 1 / sqrt(n2) from 1, n2 held within [1/2, 3/2]: one (n2 is 1 within 1e-6), two after a
     * swing clipped at 64 deg (n2 1.01 from the 2nd-order swing) or a wilder norm */
    passes = n2 - ONE30 > ONE30 >> 12 || ONE30 - n2 > ONE30 >> 12 ? 2 : 1;
    while (passes--) {
        n2 = n2 < ONE30 >> 1 ? ONE30 >> 1 : n2 > ONE30 + (ONE30 >> 1) ? ONE30 + (ONE30 >> 1) : n2;
        k = (int32_t)((3 * (int64_t)ONE30 - n2) >> 1);
        w = qmulf(w, k);
        x = qmulf(x, k);
        y = qmulf(y, k);
        z = qmulf(z, k);
        n2 = (int64_t)qmulf(w, w) + qmulf(x, x) + qmulf(y, y) + qmulf(z, z);
    }
    s->qw = w;
    s->qx = x;
    s->qy = y;
    s->qz = z;
}

/* One sample of the lite variant: the strapdown every sample, the gravity part's piece p at phase p decim / 4 */
static void step_lite(ikfq_t *s, const int32_t g[3], const int32_t a[3])
{
    int32_t n = s->decim, ph = s->phase, q[4], h[3], i;
    int here0 = 0 == ph, here1 = (1 * n) / PIECES == ph, here2 = (2 * n) / PIECES == ph;
    int here3 = (3 * n) / PIECES == ph;
    int64_t w[3];
    if (here0)
        rest(s, g, a); /* 1. */
    w[0] = (int64_t)g[0] - s->bx;
    w[1] = (int64_t)g[1] - s->by;
    w[2] = (int64_t)g[2] - s->bz;
    s->rx = (int32_t)w[0];
    s->ry = (int32_t)w[1];
    s->rz = (int32_t)w[2];
    half_step(w, s->dthq, h);
    rotate_lite(s, h[0], h[1], h[2], q);
    s->qw = q[0];
    s->qx = q[1];
    s->qy = q[2];
    s->qz = q[3];
    s->phase = ph + 1 >= n ? 0 : ph + 1;
    if (here0) {
        rate_lite(s, w[0], w[1], w[2]);
        s->bx = clamp(s->bx, s->bias_max);
        s->by = clamp(s->by, s->bias_max);
        s->bz = clamp(s->bz, s->bias_max);
    }
    /* 3. the velocity integrates every sample's force (ikf_lite.py says why): the body-frame sum over the step's
     * samples, each held within 2048 m/s^2 (no sensor reads more), the sum within 16384, turned at the last by q at
     * their middle (the mean of the middle samples') */
    for (i = 0; i < 3; i++)
        s->fsum[1 + i] = clamp(s->fsum[1 + i] + clamp(a[i], R27 - 1), ONE30 - 1);
    for (i = 0; i < 4; i++) {
        if (ph == (n - 1) / 2)
            s->qm[i] = q[i];
        if (ph == n / 2) /* the same sample for an odd n */
            s->qm[i] = (s->qm[i] >> 1) + (q[i] >> 1);
    }
    if (here1)
        predict(s, 0, 0, s->rate); /* the force enters V at the last sample (below) */
    if (here2)
        correct(s);
    if (ph == n - 1)
        force_lite(s);
    if (here3) {
        rebase_lite(s); /* 4. */
    }
}


static void start(ikfq_t *s, const int32_t g[3], const int32_t a[3])
{
    unsigned io = FMT(s).io, qb = FMT(s).quat;
    int64_t one = INT64_C(1) << qb, n, ux, uy, uz;
    int up = (int)FMT(s).bias - (int)io, i;
    n = ikfq_sqrt((int64_t)MUL(a[0], a[0], io) + MUL(a[1], a[1], io) + MUL(a[2], a[2], io), io);
    if (n < (INT64_C(1) << io) / 2)
        return;
    ux = ikfq_div(a[0], n, qb);
    uy = ikfq_div(a[1], n, qb);
    uz = ikfq_div(a[2], n, qb);
    if (uz <= -one + 2) {
        s->qw = 0;
        s->qx = (int32_t)one;
        s->qy = s->qz = 0;
    } else {
        int64_t cw = ikfq_sqrt((one >> 1) + (uz >> 1), qb);
        s->qw = (int32_t)cw;
        s->qx = ikfq_div(uy, cw, qb - 1);
        s->qy = sat(-(int64_t)ikfq_div(ux, cw, qb - 1));
        s->qz = 0;
    }
    for (i = 0; i < 3; i++) {
        s->gl[i] = up >= 0 ? sat((int64_t)g[i] * ((int64_t)1 << up)) : g[i] >> -up;
        s->al[i] = a[i];
    }
    s->started = 1;
}

void ikfq_step(ikfq_t *s, const int32_t gq[3], const int32_t a[3])
{
    const ikfq_formats_t *f = &FMT(s);
    unsigned io = f->io, qb = f->quat, bb = f->bias, sh = f->bias + f->dt - f->quat;
    int up = (int)bb - (int)io, i, last = s->phase + 1 >= s->decim;
    int32_t g[3], q[4], fx, fy;
    int64_t wx, wy, wz, rate, one = INT64_C(1) << qb, r00, r01, r02, r10, r11, r12;
    if (!s->started) {
        start(s, gq, a);
        return;
    }
    for (i = 0; i < 3; i++) /* Q8.24 holds 128 rad/s */
        g[i] = up >= 0 ? shl_sat(gq[i], up) : gq[i] >> -up;
    if (LITE(s)) {
        step_lite(s, g, a);
        return;
    }
    if (last) /* the gravity part in this sample: every decim-th */
        rest(s, g, a); /* 1. */
    /* 2. strapdown */
    wx = (int64_t)g[0] - s->bx;
    wy = (int64_t)g[1] - s->by;
    wz = (int64_t)g[2] - s->bz;
    s->rx = wx;
    s->ry = wy;
    s->rz = wz;
    rotate(s, ikfq_mul(wx, s->dthq, sh), ikfq_mul(wy, s->dthq, sh), ikfq_mul(wz, s->dthq, sh), q);
    if (!last) { /* between gravity steps q is the strapdown alone */
        s->phase++;
        s->qw = q[0];
        s->qx = q[1];
        s->qy = q[2];
        s->qz = q[3];
        return;
    }
    s->phase = 0;
    rate = ikfq_sqrt(sat((int64_t)ikfq_mul(wx, wx, 2 * bb - io) + ikfq_mul(wy, wy, 2 * bb - io)
                         + ikfq_mul(wz, wz, 2 * bb - io)), io);
    /* 3. horizontal specific force (Q.io) and the Kalman filter */
    r00 = one - 2 * ((int64_t)MUL(q[2], q[2], qb) + MUL(q[3], q[3], qb));
    r01 = 2 * ((int64_t)MUL(q[1], q[2], qb) - MUL(q[0], q[3], qb));
    r02 = 2 * ((int64_t)MUL(q[1], q[3], qb) + MUL(q[0], q[2], qb));
    r10 = 2 * ((int64_t)MUL(q[1], q[2], qb) + MUL(q[0], q[3], qb));
    r11 = one - 2 * ((int64_t)MUL(q[1], q[1], qb) + MUL(q[3], q[3], qb));
    r12 = 2 * ((int64_t)MUL(q[2], q[3], qb) - MUL(q[0], q[1], qb));
    fx = sat((int64_t)ikfq_mul(r00, a[0], qb) + ikfq_mul(r01, a[1], qb) + ikfq_mul(r02, a[2], qb));
    fy = sat((int64_t)ikfq_mul(r10, a[0], qb) + ikfq_mul(r11, a[1], qb) + ikfq_mul(r12, a[2], qb));
    predict(s, MUL(fx, s->dtq, io + f->dt - f->vel), MUL(fy, s->dtq, io + f->dt - f->vel), rate);
    correct(s);
    rebase(s, q, s->gxh, s->gyh); /* 4. */
    s->bx = clamp(s->bx, s->bias_max);
    s->by = clamp(s->by, s->bias_max);
    s->bz = clamp(s->bz, s->bias_max);
}

void ikfq_update(ikfq_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt)
{
    int32_t g[3], a[3];
    unsigned io = FMT(s).io;
    if (!(dt > 0.0) || !isfinite(gx + gy + gz + ax + ay + az + dt))
        return;
    g[0] = ikfq_to_q(gx, io);
    g[1] = ikfq_to_q(gy, io);
    g[2] = ikfq_to_q(gz, io);
    a[0] = ikfq_to_q(ax, io);
    a[1] = ikfq_to_q(ay, io);
    a[2] = ikfq_to_q(az, io);
    if (s->started)
        ikfq_set_dt(s, dt);
    ikfq_step(s, g, a);
}

void ikfq_update_q(ikfq_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt,
                   double q[4])
{
    int32_t p[4];
    double k = ldexp(1.0, -(int)FMT(s).quat);
    ikfq_update(s, gx, gy, gz, ax, ay, az, dt);
    ikfq_predicted(s, p);
    q[0] = p[0] * k;
    q[1] = p[1] * k;
    q[2] = p[2] * k;
    q[3] = p[3] * k;
}

void ikfq_run(ikfq_t *s, int32_t n, const double *rows, int32_t nlat, const int32_t *lat_half, double *out)
{
    int32_t i, j, keep = s->lat_half, p[4];
    double k = ldexp(1.0, -(int)FMT(s).quat);
    for (i = 0; i < n; i++, rows += 7) {
        ikfq_update(s, rows[0], rows[1], rows[2], rows[3], rows[4], rows[5], rows[6]);
        for (j = 0; j < nlat; j++, out += 4) {
            s->lat_half = lat_half[j];
            ikfq_predicted(s, p);
            out[0] = p[0] * k;
            out[1] = p[1] * k;
            out[2] = p[2] * k;
            out[3] = p[3] * k;
        }
    }
    s->lat_half = keep;
}

int ikfq_state(const ikfq_t *s, int64_t out[IKFQ_STATE_N])
{
    const int32_t v[20] = {s->qw, s->qx, s->qy, s->qz, s->vx, s->vy, s->dx, s->dy, s->pvv, s->pvg, s->pvd, s->pgg,
                           s->pgd, s->pdd, s->bx, s->by, s->bz, 0, 0, 0};
    int i;
    for (i = 0; i < 17; i++)
        out[i] = v[i];
    out[17] = s->rx;
    out[18] = s->ry;
    out[19] = s->rz;
    for (i = 0; i < 3; i++) {
        out[20 + i] = s->gl[i];
        out[23 + i] = s->al[i];
    }
    out[26] = s->rest_t;
    out[27] = s->at_rest;
    out[28] = s->started;
    out[29] = s->phase;
    for (i = 0; i < 3; i++)
        out[30 + i] = s->fsum[1 + i];
    for (i = 0; i < 4; i++)
        out[33 + i] = s->qm[i];
    out[37] = s->rate;
    out[38] = s->gxh;
    out[39] = s->gyh;
    return IKFQ_STATE_N;
}

unsigned ikfq_size(void)
{
    return (unsigned)sizeof(ikfq_t);
}
