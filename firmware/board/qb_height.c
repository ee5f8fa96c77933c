/* qb_height.c: the board's height estimator, fcb_sim/estimation/height.py's HeightKalman in C (the derivation:
 * docs/height.md). Height, vertical speed, accelerometer bias and the barometer's spike; a spike-robust barometer
 * update; ground detection with a trimmed-mean anchor; capture() for HEIGHT's set point (a clone state). */
#include <math.h>
#include <string.h>

#include "qb_board.h"
#include "qb_estimator.h"

#define GATE_SIGMA 3.0
#define HUBER_SIGMA 2.0
#define LEVEL_AFTER 3
#define REJUMP_WINDOW_S 1.0
#define SS_FLOOR 1e-6
static const qb_real INITIAL_SIGMA[3] = {0.03, 0.05, 0.1};

void qb_height_init(qb_height_t *h)
{
    memset(h, 0, sizeof *h);
    h->supply_sq = 1.0;
    h->thrust_c = THRUST_C0; /* the model's gain, the nominal hover's until learnt (kept by a reset: the craft's) */
    h->az_fast = G;
    qb_height_reset(h, SEA_LEVEL_PA);
}

void qb_height_reset(qb_height_t *h, qb_real pressure_pa)
{
    qb_real sh = INITIAL_SIGMA[0], sv = INITIAL_SIGMA[1], sb = INITIAL_SIGMA[2];
    uint8_t motors_off = h->motors_off;
    if (!(pressure_pa > 0.0))
        pressure_pa = SEA_LEVEL_PA; /* Python raises; the board keeps a sane reference */
    h->p_ref = pressure_pa;
    h->k_pa_per_m = pressure_pa * G * M_AIR / (R_GAS * T_ROOM);
    h->height = h->vz = h->bias = h->spike = h->az_earth = h->baro_raw = h->innovation = 0.0;
    memset(h->p, 0, sizeof h->p);
    h->p[0] = sh * sh;
    h->p[4] = sv * sv;
    h->p[7] = sb * sb;
    h->p[9] = SS_FLOOR;
    h->t_pred = 0.0;
    h->jump_sign = 0;
    h->rejumps = 0;
    h->t_jump = INFINITY;
    h->baro_rejected = h->level_changes = h->trend_resets = 0;
    h->trend = 0.0;
    h->on_ground = h->anchored = 0;
    h->rest_s = 0.0;
    h->n_ground_baro = 0;
    h->ground_baro_s = 0.0;
    h->stand_baro = 0.0;
    h->captured_height = 0.0;
    memset(h->c, 0, sizeof h->c);
    h->c00 = 0.0;
    h->stand_baro = h->acc_lp = h->ground_ref = 0.0;
    h->snapped = h->stop_n = h->stop_kind = 0;
    h->stop_v = h->stop_hold = h->stop_speed = 0.0;
    h->stops = 0;
    h->motors_off = motors_off;
}

static void propagate(qb_height_t *h, qb_real t)
{
    qb_real *p = h->p;
    qb_real hh = p[0], hv = p[1], hb = p[2], hs = p[3], vv = p[4], vb = p[5], vs = p[6], bb = p[7], bs = p[8];
    qb_real ss = p[9];
    qb_real phi = QM(exp)(-t / SPIKE_TAU_S), c = 0.5 * t * t;
    qb_real ah = hh + t * hv - c * hb, av = hv + t * vv - c * vb, ab = hb + t * vb - c * bb;
    qb_real as_ = hs + t * vs - c * bs;
    qb_real bv = vv - t * vb, bb_ = vb - t * bb, bs_ = vs - t * bs;
    /* the process noise: the accelerometer's vibration, or what the thrust model misses */
    qb_real qa = h->model_on ? MODEL_NOISE_DENSITY * MODEL_NOISE_DENSITY : ACC_NOISE_DENSITY * ACC_NOISE_DENSITY;
    qb_real qb = h->model_on ? MODEL_BIAS_WALK * MODEL_BIAS_WALK : BIAS_WALK * BIAS_WALK, t3 = t * t * t;
    qb_real ch = h->c[0], cv = h->c[1], cb = h->c[2], cs = h->c[3];
    qb_real s, ds;
    h->c[0] = ch + t * cv - c * cb;
    h->c[1] = cv - t * cb;
    h->c[2] = cb;
    h->c[3] = phi * cs;
    s = h->spike * phi;
    h->spike = s;
    ds = t * s * SPIKE_RATE_SIGMA;
    p[0] = ah + t * av - c * ab + qa * t3 / 3.0 + qb * t3 * t * t / 20.0;
    p[1] = av - t * ab + qa * t * t / 2.0 + qb * t3 * t / 8.0;
    p[2] = ab - qb * t3 / 6.0;
    p[3] = phi * as_;
    p[4] = bv - t * bb_ + qa * t + qb * t3 / 3.0;
    p[5] = bb_ - qb * t * t / 2.0;
    p[6] = phi * bs_;
    p[7] = bb + qb * t;
    p[8] = phi * bs;
    p[9] = phi * phi * ss + ds * ds + SS_FLOOR * (1.0 - phi * phi);
}

qb_real qb_height_capture(qb_height_t *h)
{
    if (h->t_pred > 0.0) {
        propagate(h, h->t_pred);
        h->t_pred = 0.0;
    }
    h->captured_height = h->height;
    memcpy(h->c, h->p, sizeof h->c); /* p[0..3]: hh hv hb hs */
    h->c00 = h->p[0];
    return h->height;
}

static void set_ground(qb_height_t *h, int on)
{
    /* the motors turn (idle's vibration or more thrust ended the rest) on the floor it knows: on the legs until
     * their thrust passes the weight */
    h->on_legs = (uint8_t)(!on && THRUST_MODEL && h->thrust_hint > 0.0 && (h->anchored || h->snapped));
    h->lifting = 0;
    if (!on) {
        qb_real var_h = INITIAL_SIGMA[0] * INITIAL_SIGMA[0];
        qb_real bb = h->p[7];
        if (!(h->anchored || h->snapped))
            var_h = h->p[0] > 1.0 ? h->p[0] : 1.0;
        if (h->anchored) /* the barometer drifted while the craft stood: its reference takes the drift out */
            h->p_ref *= QM(exp)(-(h->stand_baro - h->height) * h->k_pa_per_m / h->p_ref);
        memset(h->p, 0, sizeof h->p);
        h->p[0] = var_h;
        h->p[4] = INITIAL_SIGMA[1] * INITIAL_SIGMA[1];
        h->p[7] = bb;
        h->p[9] = SS_FLOOR;
        h->spike = 0.0;
    }
    /* on the floor it was calibrated on (close to it): the height is the floor's at once */
    h->snapped = (uint8_t)(on && QM(fabs)(h->height - h->ground_ref) < GROUND_SNAP_M);
    if (h->snapped)
        h->height = h->ground_ref;
    h->stop_hold = 0.0;
    h->stop_n = 0;
    h->on_ground = (uint8_t)on;
    h->anchored = 0;
    h->n_ground_baro = 0;
    h->ground_baro_s = 0.0;
    h->vz = 0.0;
    h->t_pred = 0.0;
}

int qb_height_unsure(const qb_height_t *h)
{
    qb_real p0 = h->p[0], t = h->t_pred;
    if (h->on_ground)
        return !(h->snapped || h->anchored);
    if (t > 0.0)
        p0 += t * (2.0 * h->p[1] + t * h->p[4]); /* the height's variance grown since the last reading */
    return p0 > UNSURE_SIGMA * UNSURE_SIGMA;
}

/* A surface stopped the craft (the jolt against the motion): the speed is zero, the height unsure. */
static void hard_stop(qb_height_t *h)
{
    qb_real sv = INITIAL_SIGMA[1];
    h->stops++;
    h->stop_kind = h->stop_v > 0.0 ? STOP_UP : STOP_DOWN;
    h->stop_speed = QM(fabs)(h->stop_v);
    h->vz = 0.0;
    h->stop_n = 0;
    h->stop_hold = STOP_HOLD_S;
    if (h->t_pred > 0.0) {
        propagate(h, h->t_pred);
        h->t_pred = 0.0;
    }
    if (h->p[0] < STOP_H_SIGMA * STOP_H_SIGMA)
        h->p[0] = STOP_H_SIGMA * STOP_H_SIGMA;
    h->p[1] = 0.0;
    h->p[4] = sv * sv;
    h->p[5] = 0.0;
    h->p[6] = 0.0;
    h->trend = 0.0;
}

/* The earth-up acceleration to integrate (m/s²): the thrust model's, c u r33 - drag - g - bias, or the
 * accelerometer's a when the motors are (nearly) off or the model is disabled. */
static qb_real thrust_accel(qb_height_t *h, qb_real az, qb_real r33, qb_real a, qb_real dt)
{
    qb_real u = h->u, c = h->thrust_c, drag = DRAG_PER_S * h->vz, thrust_fast;
    int strong = u >= THRUST_MIN, near = h->height - h->ground_ref < THRUST_ABOVE_M;
    h->model_on = 1;
    if (h->lifting) {
        if (strong && near)
            goto model; /* off the legs: the model's thrust, the floor's readings not learnt from */
        h->lifting = 0;
    }
    if (!THRUST_MODEL || !strong || near)
        goto accelerometer;
    thrust_fast = h->az_fast + drag; /* the accelerometer's mean without the drag: the thrust's */
    if (QM(fabs)(thrust_fast - c * h->u_fast) > THRUST_GATE) /* a force the model does not know: the acc's */
        goto accelerometer;
    c += ((az + drag) / u - c) * (dt * (1.0 / THRUST_TAU_S)); /* a running mean over THRUST_TAU_S */
    h->thrust_c = c;
model:
    return c * u * r33 - drag - G - h->bias;
accelerometer:
    h->model_on = 0;
    return a;
}

void qb_height_update_imu(qb_height_t *h, qb_real ax, qb_real ay, qb_real az, qb_real qw, qb_real qx, qb_real qy,
                          qb_real qz, qb_real dt)
{
    qb_real a, v, r33, kf, a_in;
    int rest, n;
    if (dt <= 0.0)
        return;
    r33 = qw * qw - qx * qx - qy * qy + qz * qz;
    a = 2.0 * (qx * qz - qw * qy) * ax + 2.0 * (qy * qz + qw * qx) * ay + r33 * az - G - h->bias;
    h->acc_lp += (QM(sqrt)(ax * ax + ay * ay + az * az) - G - h->acc_lp) * (dt / REST_TAU_S < 1.0 ? dt / REST_TAU_S : 1.0);
    rest = h->motors_off && QM(fabs)(h->acc_lp) < REST_ACC;
    h->rest_s = rest ? h->rest_s + dt : 0.0;
    if (h->on_ground != (h->rest_s >= GROUND_REST_S))
        set_ground(h, !h->on_ground);
    h->u += (h->thrust_hint - h->u) * (dt / (MOTOR_LAG_S + dt));
    kf = dt / (THRUST_FAST_S + dt);
    h->az_fast += (az - h->az_fast) * kf;
    h->u_fast += (h->u - h->u_fast) * kf;
    if (h->on_ground) {
        h->bias += a * (dt / GROUND_BIAS_TAU_S < 1.0 ? dt / GROUND_BIAS_TAU_S : 1.0);
        h->vz = 0.0;
        h->az_earth = 0.0;
        return;
    }
    if (h->on_legs) {
        if (h->thrust_c * h->u * r33 <= G && h->az_fast <= G + THRUST_GATE) {
            h->vz = 0.0; /* the floor carries what the thrust does not */
            h->az_earth = 0.0;
            return;
        }
        h->on_legs = 0; /* the thrust passes the weight: it lifts, from the floor, now */
        h->lifting = 1;
    }
    h->az_earth = a;
    a_in = thrust_accel(h, az, r33, a, dt);
    v = h->vz;
    if (h->stop_hold > 0.0) { /* the jolt of a stop: the craft stands at the surface */
        h->stop_hold -= dt;
        h->vz = 0.0;
        h->t_pred += dt;
        return;
    }
    n = h->stop_n;
    if ((a > STOP_ACC || a < -STOP_ACC) && a * (n ? h->stop_v : v) < 0.0 && (n || QM(fabs)(v) >= STOP_VZ)) {
        if (n == 0)
            h->stop_v = v;
        if (n < 255)
            h->stop_n = (uint8_t)(n + 1);
    } else if (n) {
        h->stop_n = 0;
        int near = h->stop_v > 0.0 || QM(fabs)(h->height - h->ground_ref) < STOP_FLOOR_M; /* a landing: the floor */
        if (n >= STOP_SAMPLES && n <= STOP_MAX_SAMPLES && near) { /* a jolt, as fast as a surface stops the craft */
            hard_stop(h);
            h->t_pred += dt;
            return;
        }
    }
    h->height += (v + 0.5 * a_in * dt) * dt;
    h->vz = v + a_in * dt;
    h->t_pred += dt;
    if (h->lifting && h->height < h->ground_ref) { /* just off the floor (the barometer's pull too): not below it */
        h->height = h->ground_ref;
        if (h->vz < 0.0)
            h->vz = 0.0;
    }
}

static int cmp_double(const void *a, const void *b)
{
    qb_real x = *(const qb_real *)a, y = *(const qb_real *)b;
    return (x > y) - (x < y);
}

static void sort_doubles(qb_real *v, size_t n)
{
    size_t i, j; /* insertion sort: at most QB_ANCHOR_MAX values, once per landing */
    for (i = 1; i < n; i++) {
        qb_real x = v[i];
        for (j = i; j > 0 && cmp_double(&v[j - 1], &x) > 0; j--)
            v[j] = v[j - 1];
        v[j] = x;
    }
}

static void ground_baro_update(qb_height_t *h, qb_real z, qb_real dt)
{
    qb_real sorted[QB_ANCHOR_MAX], sum = 0.0, mean;
    size_t n, cut, i;
    if (h->anchored) {
        qb_real pull = z - h->stand_baro;
        pull = pull > STAND_CLIP_M ? STAND_CLIP_M : (pull < -STAND_CLIP_M ? -STAND_CLIP_M : pull);
        h->stand_baro += pull * ((dt > 0.0 ? dt : 0.0) / STAND_TAU_S < 1.0 ? (dt > 0.0 ? dt : 0.0) / STAND_TAU_S : 1.0);
        return;
    }
    if (h->n_ground_baro < QB_ANCHOR_MAX)
        h->ground_baro[h->n_ground_baro++] = z;
    h->ground_baro_s += dt > 0.0 ? dt : 0.0;
    if (h->ground_baro_s < ANCHOR_S)
        return;
    n = h->n_ground_baro;
    memcpy(sorted, h->ground_baro, n * sizeof sorted[0]);
    sort_doubles(sorted, n);
    cut = n / 4;
    for (i = cut; i < n - cut; i++)
        sum += sorted[i];
    mean = sum / (qb_real)(n - 2 * cut);
    /* the floor is ground_ref, if the barometer agrees within GROUND_SNAP_M: what it reads there is its offset;
     * else (a table the estimate did not follow) the barometer's height stands */
    h->snapped = (uint8_t)(h->snapped && QM(fabs)(mean - h->ground_ref) < GROUND_SNAP_M);
    if (h->snapped) {
        h->p_ref *= QM(exp)(-(mean - h->ground_ref) * h->k_pa_per_m / h->p_ref);
        mean = h->ground_ref;
    }
    h->height = mean;
    h->stand_baro = h->height;
    h->anchored = 1;
    h->spike = 0.0;
}

static void baro_correct(qb_height_t *h, const qb_real p[10], qb_real nu, qb_real r)
{
    qb_real hh = p[0], hv = p[1], hb = p[2], hs = p[3], vv = p[4], vb = p[5], vs = p[6], bb = p[7], bs = p[8];
    qb_real ss = p[9];
    qb_real gh = hh + hs, gv = hv + vs, gb = hb + bs, gs = hs + ss;
    qb_real s = gh + gs + r;
    qb_real kh = gh / s, kv = gv / s, kb = gb / s, ks = gs / s;
    qb_real ch = h->c[0], cv = h->c[1], cb = h->c[2], cs = h->c[3];
    qb_real g0 = ch + cs, k0 = g0 / s;
    h->height += kh * nu;
    h->vz += kv * nu;
    h->bias += kb * nu;
    h->spike += ks * nu;
    h->captured_height += k0 * nu;
    h->c[0] = ch - k0 * gh;
    h->c[1] = cv - k0 * gv;
    h->c[2] = cb - k0 * gb;
    h->c[3] = cs - k0 * gs;
    h->c00 -= k0 * g0;
    h->p[0] = hh - kh * gh;
    h->p[1] = hv - kh * gv;
    h->p[2] = hb - kh * gb;
    h->p[3] = hs - kh * gs;
    h->p[4] = vv - kv * gv;
    h->p[5] = vb - kv * gb;
    h->p[6] = vs - kv * gs;
    h->p[7] = bb - kb * gb;
    h->p[8] = bs - kb * gs;
    h->p[9] = ss - ks * gs;
}

/* A reading far outside the prediction: the onset of a spike, or (repeated with one sign) a real level change. */
static qb_real spike_onset(qb_height_t *h, qb_real p[10], qb_real nu, qb_real z)
{
    int sign = nu > 0.0 ? 1 : -1;
    int same = sign == h->jump_sign && h->t_jump < REJUMP_WINDOW_S;
    qb_real hh = p[0], hv = p[1], hb = p[2], hs = p[3], vv = p[4], vb = p[5], vs = p[6], bb = p[7], bs = p[8];
    qb_real ss = p[9];
    h->baro_rejected++;
    h->rejumps = same ? h->rejumps + 1 : 0;
    h->jump_sign = sign;
    h->t_jump = 0.0;
    if (h->rejumps < LEVEL_AFTER) {
        p[9] += nu * nu;
        return nu;
    }
    h->rejumps = 0;
    h->level_changes++;
    h->height += h->spike;
    h->spike = 0.0;
    h->c[0] += h->c[3];
    h->c[3] = 0.0;
    nu = z - h->height;
    p[0] = hh + 2.0 * hs + ss + nu * nu;
    p[1] = hv + vs;
    p[2] = hb + bs;
    p[3] = 0.0;
    p[4] = vv;
    p[5] = vb;
    p[6] = 0.0;
    p[7] = bb;
    p[8] = 0.0;
    p[9] = SS_FLOOR;
    return nu;
}

void qb_height_update_baro(qb_height_t *h, qb_real pressure_pa, qb_real dt)
{
    qb_real z, t, nu, r, s, r_sigma, p[10];
    if (pressure_pa > 0.0)
        z = h->p_ref / h->k_pa_per_m * QM(log)(h->p_ref / pressure_pa);
    else
        z = (pressure_pa - h->p_ref) / -h->k_pa_per_m;
    h->baro_raw = z;
    if (h->on_ground) {
        h->t_pred = 0.0;
        ground_baro_update(h, z, dt);
        return;
    }
    if (h->on_legs) { /* the height held: the barometer not needed (its noise would move it) */
        h->t_pred = 0.0;
        return;
    }
    t = h->t_pred > 0.0 ? h->t_pred : (dt > 0.0 ? dt : 0.0);
    h->t_pred = 0.0;
    if (t > 0.0)
        propagate(h, t);
    h->t_jump += t;
    memcpy(p, h->p, sizeof p);
    nu = z - h->height - h->spike;
    h->innovation = nu;
    r = BARO_SIGMA_M * BARO_SIGMA_M;
    s = p[0] + 2.0 * p[3] + p[9] + r;
    r_sigma = QM(fabs)(nu) / QM(sqrt)(s);
    h->trend += TREND_GAIN * (QM(copysign)(r_sigma, nu) - h->trend);
    if (QM(fabs)(h->trend) > TREND_SIGMA) {
        p[4] += TREND_VZ_VAR;
        h->trend_resets++;
    }
    if (r_sigma > GATE_SIGMA)
        nu = spike_onset(h, p, nu, z);
    else if (r_sigma > HUBER_SIGMA)
        r *= r_sigma / HUBER_SIGMA;
    baro_correct(h, p, nu, r);
}
