/* The RAW control step in integers (ctl_q.h). */
#include "ctl_q.h"

#include "ikf_q.h"

#define FIX_ONE 65536
#define FIX_OVERFLOW (-INT32_C(0x7FFFFFFF) - 1)
#define PI_DIV_4 0x0000C90F
#define THREE_PI_DIV_4 0x00025B2F
#define HALF_PI 102944
#define ANGLE_LSB_PER_RAD 10430
#define AE_MAX 1000
#define AE_IDLE 150
#define LIFT_AE_MAX 800

/* fixed.py's table: knots (fix16 rad) and the correction at each (fix16) */
static const int32_t KNOTS[18] = {0, 572, 1144, 2002, 2860, 4003, 5433, 7149, 9151, 11438, 14298, 17729, 21733,
                                  26308, 32027, 38318, 44609, 51472};
static const int32_t CORR[18] = {0, 147, 260, 396, 494, 585, 647, 670, 647, 582, 468, 313, 139, -24, -149, -181,
                                 -122, 0};

static int32_t wrap32(int64_t v)
{
    return (int32_t)(uint32_t)(uint64_t)v;
}

/* fix16_smul: fix16_mul's rounding (half away from zero), saturating; ikf_q's 32-bit product (libgcc's 64-bit
 * multiply costs the M0 twice as much) */
static int32_t fmul(int32_t a, int32_t b)
{
    return ikfq_mul(a, b, 16);
}

/* fix16_div: rounded quotient, fix16_minimum for b == 0, fix16_overflow when it does not fit */
static int32_t fdiv(int64_t a, int64_t b)
{
    uint64_t q, r;
    if (b == 0)
        return FIX_OVERFLOW;
    q = ((uint64_t)(a < 0 ? -a : a) << 17) / (uint64_t)(b < 0 ? -b : b);
    if (q >= 0xFFFFFFFFu)
        return FIX_OVERFLOW;
    r = (q + 1) >> 1;
    return (a < 0) != (b < 0) ? -(int32_t)r : (int32_t)r;
}

static int32_t floordiv(int32_t a, int32_t b) /* b > 0 */
{
    int32_t q = a / b;
    return (a % b != 0 && a < 0) ? q - 1 : q;
}

int32_t ctlq_atan2(int32_t y, int32_t x)
{
    int64_t ay = y < 0 ? -(int64_t)y : y, m, u, c;
    int32_t r, r3, a;
    int i, mirrored;
    if (x >= 0) {
        r = fdiv(x - ay, x + ay);
        r3 = fmul(fmul(r, r), r);
        a = wrap32((int64_t)fmul(0x3240, r3) - fmul(0xFB50, r) + PI_DIV_4);
    } else {
        r = fdiv(x + ay, ay - x);
        r3 = fmul(fmul(r, r), r);
        a = wrap32((int64_t)fmul(0x3240, r3) - fmul(0xFB50, r) + THREE_PI_DIV_4);
    }
    if (y < 0)
        a = wrap32(-(int64_t)a);
    m = a < 0 ? -(int64_t)a : a;
    u = m % HALF_PI;
    mirrored = u > PI_DIV_4;
    if (mirrored)
        u = HALF_PI - u;
    for (i = 0; i < 16 && KNOTS[i + 1] <= u; i++)
        ;
    /* |correction step| <= 200 and u - knot < 2^13: the product fits 32 bits */
    c = CORR[i] + floordiv((CORR[i + 1] - CORR[i]) * (int32_t)(u - KNOTS[i]), KNOTS[i + 1] - KNOTS[i]);
    if (mirrored)
        c = -c;
    return wrap32(a < 0 ? a - c : a + c);
}

void ctlq_angles(const int32_t q[4], int32_t *phi, int32_t *theta)
{
    /* Q2.30 products to Q16.16: >> 44 of the 64-bit product, with the factor 2 of the formulas: >> 43 */
    int64_t w = q[0], x = q[1], y = q[2], z = q[3], s, cc;
    int32_t sy = (int32_t)((w * x + y * z) >> 43);
    int32_t cx = (int32_t)(FIX_ONE - ((x * x + y * y) >> 43));
    *phi = ctlq_atan2(sy, cx);
    s = (w * y - x * z) >> 43; /* sin(pitch), Q16.16 */
    if (s > FIX_ONE)
        s = FIX_ONE;
    if (s < -FIX_ONE)
        s = -FIX_ONE;
    cc = ikfq_isqrt32((uint32_t)(((int64_t)FIX_ONE * FIX_ONE - s * s))); /* cos(pitch), Q16.16 */
    *theta = -ctlq_atan2((int32_t)s, (int32_t)cc);
}

/* --- the angles cheaply (fcb_sim/estimation/ikf_lite.py: atan2_q15, angles_lite, bit for bit) ------------- */

static const int32_t ATAN_C[4] = {32744, -10533, 4804, -1282}; /* atan(t) ~ t (c1 + c3 t^2 + ...), Q15 */

int32_t ctlq_atan2_q15(int32_t y, int32_t x)
{
    uint32_t ay = y < 0 ? 0u - (uint32_t)y : (uint32_t)y, ax = x < 0 ? 0u - (uint32_t)x : (uint32_t)x, mn, mx;
    int32_t t, t2, p, a;
    mn = ay <= ax ? ay : ax;
    mx = ay <= ax ? ax : ay;
    if (mx == 0)
        return 0;
    while (mx >= UINT32_C(1) << 16) {
        mn >>= 1;
        mx >>= 1;
    }
    t = (int32_t)((mn << 15) / mx); /* one 32-bit division: libgcc's __aeabi_uidiv on the M0 */
    t2 = (t * t) >> 15;
    p = ATAN_C[2] + ((ATAN_C[3] * t2) >> 15);
    p = ATAN_C[1] + ((p * t2) >> 15);
    p = ATAN_C[0] + ((p * t2) >> 15);
    a = (p * t) >> 15;
    if (ay > ax)
        a = 51472 - a; /* pi/2, Q15 */
    if (x < 0)
        a = 102944 - a; /* pi */
    return y < 0 ? -a : a;
}

void ctlq_angles_lite(const int32_t q[4], int32_t *phi, int32_t *theta)
{
    int32_t w = q[0] >> 15, x = q[1] >> 15, y = q[2] >> 15, z = q[3] >> 15, sr, cr, sp, cp;
    sr = ((w * x) >> 14) + ((y * z) >> 14);
    cr = 32768 - ((x * x) >> 14) - ((y * y) >> 14);
    sp = ((w * y) >> 14) - ((x * z) >> 14);
    cp = (int32_t)ikfq_isqrt32((uint32_t)sr * (uint32_t)sr + (uint32_t)cr * (uint32_t)cr); /* cos(pitch), roll legs */
    *phi = 2 * ctlq_atan2_q15(sr, cr);
    *theta = -2 * ctlq_atan2_q15(sp, cp);
}

static int32_t isqrt_nr(int32_t a)
{
    uint32_t bits = 0, v, t = (uint32_t)a;
    if (a <= 0)
        return 0;
    while (t) {
        bits++;
        t >>= 1;
    }
    v = UINT32_C(1) << (bits >> 1);
    v = (v + (uint32_t)a / v) >> 1;
    v = (v + (uint32_t)a / v) >> 1;
    if ((uint64_t)v * v > (uint32_t)a)
        v--;
    return (int32_t)v;
}

void ctlq_mix(int32_t z, int32_t l, int32_t m, int32_t n, int32_t idle, int16_t ae[4])
{
    int64_t s = -(int64_t)z, li = 2 * (int64_t)l, mi = 2 * (int64_t)m, ni = n;
    int64_t out[4];
    int j;
    out[0] = (s - ni + mi) >> 2;
    out[1] = (s + ni - li) >> 2;
    out[2] = (s - ni - mi) >> 2;
    out[3] = (s + ni + li) >> 2;
    for (j = 0; j < 4; j++) {
        int64_t a = out[j] > INT32_MAX ? INT32_MAX : out[j];
        int32_t v = a > 0 ? isqrt_nr((int32_t)a) : 0;
        ae[j] = (int16_t)(v < idle ? idle : v > AE_MAX ? AE_MAX : v);
    }
}

static int32_t sat32(int64_t v)
{
    return v > INT32_MAX ? INT32_MAX : v < INT32_MIN ? INT32_MIN : (int32_t)v;
}

void ctlq_step(const ctlq_gains_t *g, const ctlq_in_t *in, int16_t ae[4])
{
    int32_t phi, theta;
    ctlq_angles(in->q, &phi, &theta);
    ctlq_law(g, in, phi, theta, ae);
}

void ctlq_law(const ctlq_gains_t *g, const ctlq_in_t *in, int32_t phi, int32_t theta, int16_t ae[4])
{
    int32_t z = 0;
    int64_t rate_sp, lm, mm, nm;
    /* L = P2 (P1 (phi_sp - phi) - p), angles in 10430 LSB per rad, rates in gyro LSB, gains Q16.16 */
    rate_sp = ((int64_t)g->p1 * ((in->roll >> 3) - (((int64_t)phi * ANGLE_LSB_PER_RAD) >> 16))) >> 16;
    lm = ((int64_t)g->p2 * (rate_sp - in->sp)) >> 16;
    rate_sp = ((int64_t)g->p1 * ((in->pitch >> 3) - (((int64_t)theta * ANGLE_LSB_PER_RAD) >> 16))) >> 16;
    mm = ((int64_t)g->p2 * (rate_sp - in->sq)) >> 16;
    nm = ((int64_t)g->yaw_p * ((in->yaw >> 4) - in->sr)) >> 16;
    if (in->lift > 0) {
        int32_t a = in->lift * LIFT_AE_MAX / 32767;
        z = -4 * a * a;
    }
    ctlq_mix(z, sat32(lm), sat32(mm), sat32(nm), AE_IDLE, ae);
}
