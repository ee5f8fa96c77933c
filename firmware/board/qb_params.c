/* qb_params.c: the parameter table (qb_params.h, generated from term.protocol.PARAMS) bound to where the board
 * keeps each value: fcb_sim/board/param_bindings.py in C. The guards in order: unknown id (UNKNOWN_PARAM), outside the
 * table's raw range (OUT_OF_RANGE), a SAFE-only parameter outside SAFE (NOT_IN_SAFE), the parameter's own rule;
 * values this board cannot run yet are refused with NOT_IMPLEMENTED (qb_board.h lists them). */
#define QB_PARAMS_TABLE /* the table's one definition */
#include <math.h>

#include "qb_board.h"

const qb_param_spec_t *qb_param_spec(int id)
{
    return id >= 1 && id <= QB_PARAM_COUNT && QB_PARAMS[id - 1].id == id ? &QB_PARAMS[id - 1] : 0;
}

/* The table's value for a raw number, rounded to the scale's decimals (as ParamSpec.from_raw does). */
static qb_real value_of(const qb_param_spec_t *s, int32_t raw)
{
    qb_real p = 1.0, v = raw * s->scale;
    int d = 0;
    while (d < 9 && QM(fabs)(QM(floor)(s->scale * p + 0.5) - s->scale * p) > 1e-9) {
        p *= 10.0;
        d++;
    }
    return QM(floor)(v * p + 0.5) / p;
}

int32_t qb_param_raw_clamped(const qb_param_spec_t *s, qb_real v)
{
    qb_real x = v / s->scale, r;
    if (!(x > (qb_real)s->lo)) /* NaN too: the low end */
        return s->lo;
    if (x >= (qb_real)s->hi)
        return s->hi;
    r = QM(floor)(x + 0.5);
    if (r - x == 0.5 && ((int32_t)r & 1))
        r -= 1.0; /* a tie goes to the even number, as Python's round() */
    return (int32_t)r;
}

/* The raw number of a value the board holds: inside the table's range by construction (every write goes through
 * qb_param_set), clipped all the same so a reading can never overflow the int32 (it once read -2147483648). */
static int32_t raw_of(const qb_param_spec_t *s, qb_real v)
{
    return qb_param_raw_clamped(s, v);
}

int32_t qb_param_get(const qb_board_t *b, int id)
{
    const qb_param_spec_t *s = qb_param_spec(id);
    const qb_gains_t *g = &b->core.g;
    switch (id) {
    case QP_PARAM_YAW_P: return raw_of(s, g->yaw_p);
    case QP_PARAM_P1: return raw_of(s, g->p1);
    case QP_PARAM_P2: return raw_of(s, g->p2);
    case QP_PARAM_HEIGHT_P: return raw_of(s, g->height_p);
    case QP_PARAM_HEIGHT_D: return raw_of(s, g->height_d);
    case QP_PARAM_HEIGHT_I: return raw_of(s, g->height_i);
    case QP_PARAM_LINK_TIMEOUT_MS: return (int32_t)QM(floor)(b->modes.link_timeout_s * 1000.0 + 0.5);
    case QP_PARAM_LINK_FAILSAFE_MS: return (int32_t)QM(floor)(b->modes.link_failsafe_s * 1000.0 + 0.5);
    case QP_PARAM_SCHEDULER: return b->scheduler;
    case QP_PARAM_TELEMETRY_HZ: return b->telemetry_hz;
    case QP_PARAM_SENSOR_PATH: return b->sensor_path;
    case QP_PARAM_LOG_SCHEME: return b->log_scheme;
    case QP_PARAM_ATTITUDE_FILTER: return b->attitude_filter;
    case QP_PARAM_K_GYRO: return b->k_gyro_raw;
    case QP_PARAM_FIXED_POINT: return b->fixed_point;
    case QP_PARAM_HEIGHT_ESTIMATOR: return b->height_estimator;
    case QP_PARAM_STICK_REACTION: return b->stick_reaction;
    case QP_PARAM_QUEUE_RULE: return b->queue_rule;
    case QP_PARAM_HEARTBEAT_MS: return b->heartbeat_ms;
    case QP_PARAM_CALIBRATION_MS: return (int32_t)QM(floor)(b->modes.calibration_s * 1000.0 + 0.5);
    case QP_PARAM_PANIC_COUNTDOWN_MS: return (int32_t)QM(floor)(b->modes.panic_countdown_s * 1000.0 + 0.5);
    case QP_PARAM_TRIM_STEP: return b->modes.trim_step;
    case QP_PARAM_LIFT_STEP: return b->modes.lift_step;
    default: return 0;
    }
}

/* The RAW filter: ikf's fixed-point twin (est.fixed_point is kept and reported; ikf is fixed point either way), or
 * the report's complementary filter, in Q16.16 or in qb_real by est.fixed_point and with est.k_gyro's K_gyro, as
 * param_bindings.build_filter (not on the M0 image: QB_REPORT_EST). A change starts the filter afresh, as the
 * Python board builds a new one. */
static uint8_t set_filter(qb_board_t *b, int32_t filter, int32_t fixed, int32_t k_gyro_raw)
{
    if (fixed && filter == QB_ATTITUDE_QGATE)
        return QP_NAK_BAD_ARGUMENT; /* no fixed-point twin of this filter */
    if (filter != QB_ATTITUDE_IKF && (!QB_REPORT_EST || filter != QB_ATTITUDE_COMPLEMENTARY))
        return QP_NAK_NOT_IMPLEMENTED;
    b->attitude_filter = filter;
    b->fixed_point = fixed;
    b->k_gyro_raw = k_gyro_raw;
    qb_flight_set_filter(&b->core, filter, fixed, value_of(qb_param_spec(QP_PARAM_K_GYRO), k_gyro_raw));
    return QP_NAK_OK;
}

static uint8_t set_bound(qb_board_t *b, int id, int32_t raw, qb_real v)
{
    qb_gains_t *g = &b->core.g;
    switch (id) {
    case QP_PARAM_YAW_P: g->yaw_p = v; break;
    case QP_PARAM_P1: g->p1 = v; break;
    case QP_PARAM_P2: g->p2 = v; break;
    case QP_PARAM_HEIGHT_P: g->height_p = v; break;
    case QP_PARAM_HEIGHT_D: g->height_d = v; break;
    case QP_PARAM_HEIGHT_I: g->height_i = v; break;
    case QP_PARAM_LINK_TIMEOUT_MS: b->modes.link_timeout_s = b->cfg.link_timeout_s = raw / 1000.0; break;
    case QP_PARAM_LINK_FAILSAFE_MS: b->modes.link_failsafe_s = b->cfg.link_failsafe_s = raw / 1000.0; break;
    case QP_PARAM_SCHEDULER: b->scheduler = raw; break; /* kept and reported; the loop is round robin (no slack rule) */
    case QP_PARAM_TELEMETRY_HZ: b->telemetry_hz = raw; break;
    case QP_PARAM_SENSOR_PATH: b->sensor_path = raw; break;
    case QP_PARAM_LOG_SCHEME: /* a fresh log in the new scheme; refused while the log holds anything */
        if (b->log.used)
            return QP_NAK_LOG_BUSY;
        b->log_scheme = raw;
        qb_log_init(&b->log, b->log.size, (uint8_t)raw);
        break;
    case QP_PARAM_ATTITUDE_FILTER: return set_filter(b, raw, b->fixed_point, b->k_gyro_raw);
    case QP_PARAM_K_GYRO: return set_filter(b, b->attitude_filter, b->fixed_point, raw); /* the filter afresh */
    case QP_PARAM_FIXED_POINT: return set_filter(b, b->attitude_filter, raw, b->k_gyro_raw);
    case QP_PARAM_HEIGHT_ESTIMATOR:
        if (raw != QB_HEIGHT_KALMAN && !QB_REPORT_EST)
            return QP_NAK_NOT_IMPLEMENTED; /* the report's Figure 10 estimator: not on the M0 image (flash) */
        b->height_estimator = raw;
        qb_flight_set_height(&b->core, raw == QB_HEIGHT_COMPLEMENTARY); /* afresh at the calibration's pressure */
        break;
    case QP_PARAM_STICK_REACTION: b->stick_reaction = raw; break;
    case QP_PARAM_QUEUE_RULE: b->queue_rule = raw; break;
    case QP_PARAM_TRIM_STEP: b->modes.trim_step = raw; break;
    case QP_PARAM_LIFT_STEP: b->modes.lift_step = raw; break;
    case QP_PARAM_HEARTBEAT_MS: b->heartbeat_ms = raw; break; /* the heartbeat timer's next period */
    case QP_PARAM_CALIBRATION_MS: b->modes.calibration_s = raw / 1000.0; break;
    case QP_PARAM_PANIC_COUNTDOWN_MS:
        b->modes.panic_countdown_s = raw / 1000.0;
        b->core.panic_hold = raw != 0; /* the report's PANIC: a fixed level, no descent loop */
        break;
    default: return QP_NAK_UNKNOWN_PARAM;
    }
    return QP_NAK_OK;
}

int qb_param_broken_rule(const qb_board_t *b, int id, int32_t raw)
{
    int i;
    for (i = 0; i < QB_RULE_COUNT; i++) { /* fcb_sim/board/param_bindings.py's broken_rule */
        const qb_param_rule_t *r = &QB_RULES[i];
        int32_t big, small; /* raw values of at most 24 bits, factors small: the product fits */
        if (id != r->big && id != r->small)
            continue;
        big = id == r->big ? raw : qb_param_get(b, r->big);
        small = id == r->small ? raw : qb_param_get(b, r->small);
        if (big < r->factor * small)
            return i;
    }
    return -1;
}

uint8_t qb_param_set(qb_board_t *b, int id, int32_t raw, int mode_guard)
{
    const qb_param_spec_t *s = qb_param_spec(id);
    if (!s)
        return QP_NAK_UNKNOWN_PARAM;
    if (raw < s->lo || raw > s->hi)
        return QP_NAK_OUT_OF_RANGE;
    if (mode_guard && b->modes.mode != QP_MODE_SAFE) {
        if (!s->in_flight)
            return QP_NAK_NOT_IN_SAFE;
        if (s->shorter_in_flight && raw > qb_param_get(b, id))
            return QP_NAK_ONLY_SHORTER_IN_FLIGHT; /* a link timeout may not grow (or go off) in flight */
    }
    if (mode_guard && qb_param_broken_rule(b, id, raw) >= 0) /* a command's set (a preset's: the whole set, after) */
        return QP_NAK_PARAM_RULE;
    return set_bound(b, id, raw, value_of(s, raw));
}
