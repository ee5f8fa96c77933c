/* ikf in doubles: step for step fcb_sim/estimation/ikf.py (ikf_f.h). Every expression keeps the Python's order
 * of operations; change one and the other together. */
#include "ikf_f.h"

#include <math.h>

#define G0 9.81
#define P_GG0 0.1
#define P_VV_MAX 1e6
#define RATE_MAX 1e4 /* ikf.py: samples no sensor gives are skipped */
#define ACC_MAX 1e5
#define DT_MAX 60.0

void ikff_init(ikff_t *s, const ikff_params_t *p)
{
    s->p = *p;
    ikff_reset(s);
}

void ikff_reset(ikff_t *s)
{
    s->w = 1.0;
    s->x = s->y = s->z = 0.0;
    s->vx = s->vy = s->dx = s->dy = 0.0;
    s->pvv = s->pvg = s->pvd = 0.0;
    s->pgg = P_GG0;
    s->pgd = 0.0;
    s->pdd = s->p.drift_init;
    s->bx = s->by = s->bz = 0.0;
    s->rx = s->ry = s->rz = 0.0;
    s->gl[0] = s->gl[1] = s->gl[2] = 0.0;
    s->al[0] = s->al[1] = 0.0;
    s->al[2] = G0;
    s->rest_t = 0.0;
    s->at_rest = 0;
    s->started = 0;
}

void ikff_quaternion(const ikff_t *s, double q[4])
{
    double w = s->w, x = s->x, y = s->y, z = s->z, rx = s->rx, ry = s->ry, rz = s->rz;
    double rate = sqrt(rx * rx + ry * ry + rz * rz), half = 0.5 * rate * s->p.latency, sn, c, dx, dy, dz;
    if (half <= 1e-12) {
        q[0] = w;
        q[1] = x;
        q[2] = y;
        q[3] = z;
        return;
    }
    sn = sin(half) / rate;
    c = cos(half);
    dx = rx * sn;
    dy = ry * sn;
    dz = rz * sn;
    q[0] = w * c - x * dx - y * dy - z * dz;
    q[1] = w * dx + x * c + y * dz - z * dy;
    q[2] = w * dy - x * dz + y * c + z * dx;
    q[3] = w * dz + x * dy - y * dx + z * c;
}

static void start(ikff_t *s, double gx, double gy, double gz, double ax, double ay, double az)
{
    double n = sqrt(ax * ax + ay * ay + az * az), ux, uy, uz;
    if (n < 0.5)
        return;
    ux = ax / n;
    uy = ay / n;
    uz = az / n;
    if (uz < -0.999999) {
        s->w = 0.0;
        s->x = 1.0;
        s->y = s->z = 0.0;
    } else {
        double k = 1.0 / sqrt((1.0 + uz) * (1.0 + uz) + uy * uy + ux * ux);
        s->w = (1.0 + uz) * k;
        s->x = uy * k;
        s->y = -ux * k;
        s->z = 0.0;
    }
    s->gl[0] = gx;
    s->gl[1] = gy;
    s->gl[2] = gz;
    s->al[0] = ax;
    s->al[1] = ay;
    s->al[2] = az;
    s->started = 1;
}

static void rest(ikff_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt)
{
    double *gl = s->gl, *al = s->al, kr = dt / (s->p.rest_tau + dt), m = s->p.bias_max;
    double dgx, dgy, dgz, dax, day, daz;
    int still;
    gl[0] += kr * (gx - gl[0]);
    gl[1] += kr * (gy - gl[1]);
    gl[2] += kr * (gz - gl[2]);
    al[0] += kr * (ax - al[0]);
    al[1] += kr * (ay - al[1]);
    al[2] += kr * (az - al[2]);
    dgx = gx - gl[0];
    dgy = gy - gl[1];
    dgz = gz - gl[2];
    dax = ax - al[0];
    day = ay - al[1];
    daz = az - al[2];
    still = dgx * dgx + dgy * dgy + dgz * dgz < s->p.rest_gyro * s->p.rest_gyro
            && dax * dax + day * day + daz * daz < s->p.rest_acc * s->p.rest_acc
            && fabs(gl[0]) < m && fabs(gl[1]) < m && fabs(gl[2]) < m;
    s->rest_t = still ? s->rest_t + dt : 0.0;
    s->at_rest = s->rest_t >= s->p.rest_time;
    if (s->at_rest) {
        double kb = dt / (s->p.rest_bias_tau + dt);
        s->bx += kb * (gl[0] - s->bx);
        s->by += kb * (gl[1] - s->by);
        s->bz += kb * (gl[2] - s->bz);
    }
}

static void gravity(ikff_t *s, double fx, double fy, double rate, double dt, double *gxh_out, double *gyh_out)
{
    double e = rate * dt, vx = s->vx + fx * dt, vy = s->vy + fy * dt, gxh = s->dx * e, gyh = s->dy * e;
    double pvv = s->pvv, pvg = s->pvg, pvd = s->pvd, pgg = s->pgg, pgd = s->pgd, pdd = s->pdd;
    double a_vv = pvv - 2.0 * dt * pvg + dt * dt * pgg;
    double a_vg = pvg + e * pvd - dt * pgg - dt * e * pgd;
    double a_vd = pvd - dt * pgd;
    double a_gg = pgg + 2.0 * e * pgd + e * e * pdd + s->p.q_g0 * (1.0 + s->p.k_rot * rate) * dt;
    double a_gd = pgd + e * pdd;
    double a_dd = pdd + s->p.drift_noise * e;
    double inv_s = 1.0 / (a_vv + (s->at_rest ? s->p.rest_r : 1.0) / dt);
    double kv = a_vv * inv_s, kg = a_vg * inv_s, kd = a_vd * inv_s, pv;
    gxh -= kg * vx;
    gyh -= kg * vy;
    s->dx -= kd * vx;
    s->dy -= kd * vy;
    s->vx = vx - kv * vx;
    s->vy = vy - kv * vy;
    pv = a_vv - kv * a_vv;
    s->pvv = P_VV_MAX < pv ? P_VV_MAX : pv; /* Python's min(pv, P_VV_MAX) */
    s->pvg = a_vg - kv * a_vg;
    s->pvd = a_vd - kv * a_vd;
    s->pgg = a_gg - kg * a_vg;
    s->pgd = a_gd - kg * a_vd;
    s->pdd = a_dd - kd * a_vd;
    *gxh_out = gxh;
    *gyh_out = gyh;
}

static void rebase(ikff_t *s, double w, double x, double y, double z, double gxh, double gyh)
{
    double h2 = gxh * gxh + gyh * gyh, gz_, cw, cx, cy, k, n;
    gz_ = h2 < 0.81 * G0 * G0 ? sqrt(G0 * G0 - h2) : 0.4359 * G0;
    cw = G0 + gz_;
    cx = gyh;
    cy = -gxh;
    k = 1.0 / sqrt(cw * cw + cx * cx + cy * cy);
    cw = cw * k;
    cx = cx * k;
    cy = cy * k;
    {
        double w2 = cw * w - cx * x - cy * y, x2 = cw * x + cx * w + cy * z, y2 = cw * y - cx * z + cy * w;
        double z2 = cw * z + cx * y - cy * x;
        w = w2;
        x = x2;
        y = y2;
        z = z2;
    }
    n = 1.0 / sqrt(w * w + x * x + y * y + z * z);
    s->w = w * n;
    s->x = x * n;
    s->y = y * n;
    s->z = z * n;
}

void ikff_update(ikff_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt)
{
    double wx, wy, wz, w, x, y, z, rate, half, fx, fy, gxh, gyh, m;
    if (!(0.0 < dt && dt < DT_MAX && fabs(gx) + fabs(gy) + fabs(gz) < RATE_MAX
          && fabs(ax) + fabs(ay) + fabs(az) < ACC_MAX))
        return; /* NaN fails every comparison too */
    if (!s->started) {
        start(s, gx, gy, gz, ax, ay, az);
        return;
    }
    rest(s, gx, gy, gz, ax, ay, az, dt);
    wx = gx - s->bx;
    wy = gy - s->by;
    wz = gz - s->bz;
    s->rx = wx;
    s->ry = wy;
    s->rz = wz;
    w = s->w;
    x = s->x;
    y = s->y;
    z = s->z;
    rate = sqrt(wx * wx + wy * wy + wz * wz);
    half = 0.5 * rate * dt;
    if (half > 1e-12) {
        double sn = sin(half) / rate, c = cos(half), dx = wx * sn, dy = wy * sn, dz = wz * sn;
        double w2 = w * c - x * dx - y * dy - z * dz, x2 = w * dx + x * c + y * dz - z * dy;
        double y2 = w * dy - x * dz + y * c + z * dx, z2 = w * dz + x * dy - y * dx + z * c;
        w = w2;
        x = x2;
        y = y2;
        z = z2;
    }
    fx = (1.0 - 2.0 * (y * y + z * z)) * ax + 2.0 * (x * y - w * z) * ay + 2.0 * (x * z + w * y) * az;
    fy = 2.0 * (x * y + w * z) * ax + (1.0 - 2.0 * (x * x + z * z)) * ay + 2.0 * (y * z - w * x) * az;
    gravity(s, fx, fy, rate, dt, &gxh, &gyh);
    rebase(s, w, x, y, z, gxh, gyh);
    m = s->p.bias_max;
    s->bx = s->bx > m ? m : s->bx < -m ? -m : s->bx;
    s->by = s->by > m ? m : s->by < -m ? -m : s->by;
    s->bz = s->bz > m ? m : s->bz < -m ? -m : s->bz;
}

void ikff_update_q(ikff_t *s, double gx, double gy, double gz, double ax, double ay, double az, double dt,
                   double q[4])
{
    ikff_update(s, gx, gy, gz, ax, ay, az, dt);
    ikff_quaternion(s, q);
}

unsigned ikff_size(void)
{
    return (unsigned)sizeof(ikff_t);
}
