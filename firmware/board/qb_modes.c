/* qb_modes.c: the mode state machine with its guards, and the calibration sums: fcb_sim/board/modes.py and
 * calibration.py in C. The same table of transitions, the same guards in the same order, so the same NAK reason
 * for the same refusal; the same events in the same order. */
#include <math.h>
#include <string.h>

#include "qb_board.h"

/* Guards, evaluated in ascending bit order (the order of fcb_sim.board.modes._ARM and the rows). */
enum { G_ZERO_LIFT = 1, G_NEUTRAL = 2, G_NO_CRASH = 4, G_BATTERY = 8, G_CALIBRATED = 16, G_FROM_BASE = 32,
       G_PANIC_DONE = 64, G_CAL_TIME = 128 };
enum { TRIG_REQUEST, TRIG_AUTO };
#define ARM (G_ZERO_LIFT | G_NEUTRAL | G_NO_CRASH | G_BATTERY)

typedef struct {
    uint8_t source, target, trigger, guards;
} row_t;

static const row_t ROWS[] = {
    {QP_MODE_SAFE, QP_MODE_MANUAL, TRIG_REQUEST, ARM},
    {QP_MODE_SAFE, QP_MODE_CALIBRATION, TRIG_REQUEST, G_ZERO_LIFT | G_NEUTRAL | G_NO_CRASH},
    {QP_MODE_SAFE, QP_MODE_YAW, TRIG_REQUEST, ARM | G_CALIBRATED},
    {QP_MODE_SAFE, QP_MODE_FULL, TRIG_REQUEST, ARM | G_CALIBRATED},
    {QP_MODE_SAFE, QP_MODE_RAW, TRIG_REQUEST, ARM | G_CALIBRATED},
    {QP_MODE_CALIBRATION, QP_MODE_SAFE, TRIG_AUTO, G_CAL_TIME},
    {QP_MODE_CALIBRATION, QP_MODE_SAFE, TRIG_REQUEST, 0},
    {QP_MODE_FULL, QP_MODE_HEIGHT, TRIG_REQUEST, 0},
    {QP_MODE_RAW, QP_MODE_HEIGHT, TRIG_REQUEST, 0},
    {QP_MODE_HEIGHT, QP_MODE_FULL, TRIG_REQUEST, G_FROM_BASE},
    {QP_MODE_HEIGHT, QP_MODE_RAW, TRIG_REQUEST, G_FROM_BASE},
    {QP_MODE_MANUAL, QP_MODE_SAFE, TRIG_REQUEST, G_ZERO_LIFT},
    {QP_MODE_YAW, QP_MODE_SAFE, TRIG_REQUEST, G_ZERO_LIFT},
    {QP_MODE_FULL, QP_MODE_SAFE, TRIG_REQUEST, G_ZERO_LIFT},
    {QP_MODE_RAW, QP_MODE_SAFE, TRIG_REQUEST, G_ZERO_LIFT},
    {QP_MODE_HEIGHT, QP_MODE_SAFE, TRIG_REQUEST, G_ZERO_LIFT},
    {QP_MODE_MANUAL, QP_MODE_PANIC, TRIG_REQUEST, 0},
    {QP_MODE_CALIBRATION, QP_MODE_PANIC, TRIG_REQUEST, 0},
    {QP_MODE_YAW, QP_MODE_PANIC, TRIG_REQUEST, 0},
    {QP_MODE_FULL, QP_MODE_PANIC, TRIG_REQUEST, 0},
    {QP_MODE_RAW, QP_MODE_PANIC, TRIG_REQUEST, 0},
    {QP_MODE_HEIGHT, QP_MODE_PANIC, TRIG_REQUEST, 0},
    {QP_MODE_PANIC, QP_MODE_SAFE, TRIG_AUTO, G_PANIC_DONE},
};

static void emit(qb_modes_t *m, uint8_t code, int32_t arg)
{
    if (m->n_events < QB_EVENTS) {
        m->events[m->n_events].code = code;
        m->events[m->n_events].arg = arg;
        m->n_events++;
    }
}

void qb_modes_event(qb_modes_t *m, uint8_t code, int32_t arg)
{
    emit(m, code, arg);
}

int qb_modes_take_event(qb_modes_t *m, qb_event_t *ev)
{
    if (m->n_events == 0)
        return 0;
    *ev = m->events[0];
    memmove(&m->events[0], &m->events[1], (size_t)(m->n_events - 1) * sizeof m->events[0]);
    m->n_events--;
    return 1;
}

void qb_modes_init(qb_modes_t *m, qb_real link_timeout_s, int32_t panic_level)
{
    memset(m, 0, sizeof *m);
    m->link_timeout_s = link_timeout_s;
    m->link_failsafe_s = QB_PARAMS[QP_PARAM_LINK_FAILSAFE_MS - 1].def / 1000.0;
    m->calibration_s = QB_PARAMS[QP_PARAM_CALIBRATION_MS - 1].def / 1000.0;
    m->panic_countdown_s = QB_PARAMS[QP_PARAM_PANIC_COUNTDOWN_MS - 1].def / 1000.0;
    m->panic_level = panic_level;
    m->trim_step = QB_PARAMS[QP_PARAM_TRIM_STEP - 1].def;
    m->lift_step = QB_PARAMS[QP_PARAM_LIFT_STEP - 1].def;
    m->mode = m->previous = QP_MODE_SAFE;
    m->height_base = QP_MODE_FULL;
    m->battery = -1;
}

static int32_t clip(int32_t v, int32_t lo, int32_t hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

int32_t qb_modes_lift(const qb_modes_t *m)
{
    return clip((int32_t)m->js.lift + m->trim_lift, 0, QP_STICK_MAX);
}

void qb_modes_sticks(const qb_modes_t *m, int32_t out[4])
{
    if (m->link_hold) { /* the failsafe's stage 1: level, with the lift it had */
        out[0] = out[1] = out[2] = 0;
        out[3] = m->hold_lift;
        return;
    }
    out[0] = clip((int32_t)m->js.roll + m->trim_roll, -QP_STICK_MAX, QP_STICK_MAX);
    out[1] = clip((int32_t)m->js.pitch + m->trim_pitch, -QP_STICK_MAX, QP_STICK_MAX);
    out[2] = clip((int32_t)m->js.yaw + m->trim_yaw, -QP_STICK_MAX, QP_STICK_MAX);
    out[3] = qb_modes_lift(m);
}

/* The lift trim after `steps` presses, finer near hover: term/core/protocol's lift_trim_after, press by press (the
 * closed form cost the M0 248 bytes of flash it has not got; a press stops at the trim's clip, so Z's -32767 at
 * the default step is at most ~180 turns) */
static int32_t lift_trim_after(int32_t trim, int32_t steps, int32_t lift_step, int32_t js_lift)
{
    const int32_t coarse = lift_step > 1 ? lift_step : 1;
    const int32_t fine = lift_step / QP_LIFT_FINE_DIVISOR > 1 ? lift_step / QP_LIFT_FINE_DIVISOR : 1;
    const int32_t dir = steps > 0 ? 1 : -1, edge = steps > 0 ? QP_STICK_MAX : 0;
    while (steps != 0 && trim != edge) {
        int32_t level = js_lift + trim, to = level + dir * fine;
        int32_t in_band = (dir > 0 ? level : to) >= QP_LIFT_FINE_FROM && (dir > 0 ? to : level) <= QP_LIFT_FINE_TO;
        trim += dir * (in_band ? fine : coarse);
        trim = trim < 0 ? 0 : trim > QP_STICK_MAX ? QP_STICK_MAX : trim;
        steps -= dir;
    }
    return trim;
}

int32_t qb_modes_adjust_trim(qb_modes_t *m, int axis, int32_t steps)
{
    int64_t v;
    int32_t *t;
    if (axis == 0) {
        m->trim_lift = lift_trim_after(m->trim_lift, steps, m->lift_step, m->js.lift);
        return m->trim_lift;
    }
    t = axis == 1 ? &m->trim_roll : axis == 2 ? &m->trim_pitch : &m->trim_yaw;
    v = (int64_t)*t + (int64_t)steps * m->trim_step;
    *t = (int32_t)(v < -TRIM_LIMIT ? -TRIM_LIMIT : v > TRIM_LIMIT ? TRIM_LIMIT : v);
    return *t;
}

int qb_modes_flying(const qb_modes_t *m)
{
    return QP_IS_FLIGHT_MODE(m->mode);
}

int qb_modes_motors_enabled(const qb_modes_t *m)
{
    return m->mode != QP_MODE_SAFE && m->mode != QP_MODE_CALIBRATION;
}

/* --- calibration sums (fcb_sim/board/calibration.py) ------------------------------------------------------------ */

void qb_modes_cal_add(qb_modes_t *m, int var, int32_t v)
{
    m->sums[var] += v;
    m->counts[var]++;
}

int32_t qb_modes_cal_mean(const qb_modes_t *m, int var)
{
    int64_t n = m->counts[var], s = m->sums[var], num, den, q;
    if (n == 0)
        return 0;
    num = 2 * s + n; /* (2s + n) // (2n): Python's floor division, in unsigned (the M0 links one 64-bit divide) */
    den = 2 * n;
    q = num >= 0 ? (int64_t)((uint64_t)num / (uint64_t)den)
                 : -(int64_t)(((uint64_t)(-num) + (uint64_t)den - 1u) / (uint64_t)den);
    return (int32_t)q;
}

/* --- the panic timer ---------------------------------------------------------------------------------------- */

static int ramp_from(const qb_modes_t *m, qb_real *t0)
{
    qb_real timeout;
    if (m->panic_countdown_s > 0.0) { /* the report's: when the countdown ends the motors stop (no ramp) */
        *t0 = m->panic_started + m->panic_countdown_s;
        return m->now >= *t0;
    }
    if (m->panic_landed_set) {
        *t0 = m->panic_landed_at;
        return 1;
    }
    timeout = m->panic_started + PANIC_TIMEOUT_S;
    if (m->now >= timeout) {
        *t0 = timeout;
        return 1;
    }
    return 0;
}

static int panic_finished(const qb_modes_t *m)
{
    qb_real t0;
    if (m->panic_start_level == 0)
        return 1;
    return ramp_from(m, &t0) && m->now >= t0 + (m->panic_countdown_s > 0.0 ? 0.0 : PANIC_RAMP_S);
}

qb_real qb_modes_panic_scale(qb_modes_t *m, qb_real now)
{
    qb_real t0, s;
    if (m->mode != QP_MODE_PANIC)
        return 0.0;
    if (now > m->now)
        m->now = now;
    if (!ramp_from(m, &t0))
        return 1.0;
    if (m->panic_countdown_s > 0.0)
        return 0.0;
    s = 1.0 - (now - t0) / PANIC_RAMP_S;
    return s > 0.0 ? s : 0.0;
}

void qb_modes_panic_ground(qb_modes_t *m, qb_real now)
{
    if (m->mode == QP_MODE_PANIC && !m->panic_landed_set) {
        m->panic_landed_at = now;
        m->panic_landed_set = 1;
    }
}

/* --- guards and transitions --------------------------------------------------------------------------------- */

static uint8_t guard(const qb_modes_t *m, int bit)
{
    int32_t s[4];
    switch (bit) {
    case G_ZERO_LIFT:
        return qb_modes_lift(m) <= QP_LIFT_ZERO ? QP_NAK_OK : QP_NAK_LIFT_NOT_ZERO;
    case G_NEUTRAL:
        qb_modes_sticks(m, s);
        return (s[0] <= QP_STICK_NEUTRAL && s[0] >= -QP_STICK_NEUTRAL && s[1] <= QP_STICK_NEUTRAL &&
                s[1] >= -QP_STICK_NEUTRAL && s[2] <= QP_STICK_NEUTRAL && s[2] >= -QP_STICK_NEUTRAL)
                   ? QP_NAK_OK : QP_NAK_STICKS_NOT_NEUTRAL;
    case G_NO_CRASH:
        return m->crashed ? QP_NAK_CRASHED : QP_NAK_OK;
    case G_BATTERY:
        if (m->battery_low_latched)
            return QP_NAK_BATTERY_LOW;
        return (m->battery < 0 || m->battery >= QP_BATTERY_LOW) ? QP_NAK_OK : QP_NAK_BATTERY_LOW;
    case G_CALIBRATED:
        return m->calibrated ? QP_NAK_OK : QP_NAK_NOT_CALIBRATED;
    case G_FROM_BASE:
        return m->height_base == m->pending_target ? QP_NAK_OK : QP_NAK_INVALID_TRANSITION;
    case G_PANIC_DONE:
        return panic_finished(m) ? QP_NAK_OK : QP_NAK_PANIC_ACTIVE;
    case G_CAL_TIME:
        /* 0: no timer, the pilot ends it (the report's) */
        return m->calibration_s > 0.0 && m->now - m->calibration_started >= m->calibration_s ? QP_NAK_OK
                                                                                              : QP_NAK_BUSY;
    default:
        return QP_NAK_OK;
    }
}

static uint8_t check(qb_modes_t *m, uint8_t target, int trigger)
{
    size_t i;
    int bit;
    if (target == m->mode)
        return QP_NAK_OK;
    if (m->mode == QP_MODE_PANIC && trigger == TRIG_REQUEST)
        return QP_NAK_PANIC_ACTIVE;
    for (i = 0; i < sizeof ROWS / sizeof ROWS[0]; i++) {
        if (ROWS[i].source == m->mode && ROWS[i].target == target && ROWS[i].trigger == trigger)
            break;
    }
    if (i == sizeof ROWS / sizeof ROWS[0])
        return QP_NAK_INVALID_TRANSITION;
    m->pending_target = target;
    for (bit = 1; bit <= G_CAL_TIME; bit <<= 1) {
        if (ROWS[i].guards & bit) {
            uint8_t reason = guard(m, bit);
            if (reason != QP_NAK_OK) {
                m->pending_target = 0;
                return reason;
            }
        }
    }
    m->pending_target = 0;
    return QP_NAK_OK;
}

static void leave(qb_modes_t *m, uint8_t mode)
{
    if (mode == QP_MODE_CALIBRATION) {
        uint32_t n = m->counts[QB_CAL_GX];
        if (n >= CALIBRATION_MIN_SAMPLES) {
            m->calibrated = 1;
            emit(m, QP_EVENT_CODE_CALIBRATION_DONE, (int32_t)n);
        }
    } else if (mode == QP_MODE_PANIC) {
        emit(m, QP_EVENT_CODE_PANIC_DONE, 0);
    }
}

static void enter(qb_modes_t *m, uint8_t mode, qb_real now)
{
    int32_t level;
    switch (mode) {
    case QP_MODE_SAFE:
        m->trim_lift = 0; /* a fresh flight starts from zero lift trim */
        break;
    case QP_MODE_CALIBRATION:
        memset(m->sums, 0, sizeof m->sums);
        memset(m->counts, 0, sizeof m->counts);
        m->calibration_started = now;
        break;
    case QP_MODE_PANIC:
        m->panic_started = now;
        m->panic_landed_set = 0;
        level = m->motor_level > 0 ? m->motor_level : 0; /* never spin the motors up to enter PANIC */
        m->panic_start_level = level < m->panic_level ? level : m->panic_level;
        break;
    case QP_MODE_HEIGHT:
        m->height_base = m->previous;
        break;
    default:
        break;
    }
}

static void change(qb_modes_t *m, uint8_t target, qb_real now)
{
    uint8_t old = m->mode;
    m->link_hold = 0; /* a new mode (PANIC, a crash's SAFE) ends stage 1 */
    leave(m, old);
    m->previous = old;
    m->mode = target;
    enter(m, target, now);
    emit(m, QP_EVENT_CODE_MODE_CHANGED, (int32_t)(((uint32_t)old << 8) | target));
    if (m->on_change)
        m->on_change(m->ctx, old, target);
}

uint8_t qb_modes_request(qb_modes_t *m, int32_t target, qb_real now)
{
    uint8_t reason;
    if (target < QP_MODE_SAFE || target > QP_MODE_WIRELESS || target == QP_MODE_WIRELESS)
        return QP_NAK_BAD_ARGUMENT;
    if (target == QP_MODE_PANIC && (m->mode == QP_MODE_SAFE || m->mode == QP_MODE_PANIC))
        return QP_NAK_OK;
    if (target == m->mode) {
        if (target == QP_MODE_SAFE)
            m->trim_lift = 0; /* 0 in SAFE still zeroes the lift trim */
        return QP_NAK_OK;
    }
    reason = check(m, (uint8_t)target, TRIG_REQUEST);
    if (reason != QP_NAK_OK) {
        emit(m, QP_EVENT_CODE_REFUSED, (int32_t)(((uint32_t)reason << 8) | (uint32_t)target));
        return reason;
    }
    change(m, (uint8_t)target, now);
    return QP_NAK_OK;
}

int qb_modes_panic(qb_modes_t *m, qb_real now)
{
    if (qb_modes_flying(m) || m->mode == QP_MODE_CALIBRATION)
        change(m, QP_MODE_PANIC, now);
    return m->mode == QP_MODE_PANIC;
}

void qb_modes_crash(qb_modes_t *m, qb_real now, int32_t speed_mm_s)
{
    m->crashed = 1;
    emit(m, QP_EVENT_CODE_CRASH, speed_mm_s);
    if (m->mode != QP_MODE_SAFE)
        change(m, QP_MODE_SAFE, now);
}

uint8_t qb_modes_ack_crash(qb_modes_t *m)
{
    if (m->mode != QP_MODE_SAFE)
        return QP_NAK_NOT_IN_SAFE;
    m->crashed = 0;
    return QP_NAK_OK;
}

void qb_modes_tick(qb_modes_t *m, qb_real now)
{
    m->now = now;
    if ((m->mode == QP_MODE_CALIBRATION || m->mode == QP_MODE_PANIC) &&
        check(m, QP_MODE_SAFE, TRIG_AUTO) == QP_NAK_OK)
        change(m, QP_MODE_SAFE, now);
}

/* cos by its series after reducing to [-pi, pi] (error < 1e-13): the M0 build then links no cos/acos and
 * their argument reduction (about 5 KB); acos(c) is QM(atan2)(QM(sqrt)(1 - c^2), c). */
static qb_real cos_series(qb_real x)
{
    const qb_real pi = 3.14159265358979323846;
    qb_real x2, term = 1.0, sum = 1.0;
    int n;
    x -= 2.0 * pi * QM(floor)(x / (2.0 * pi) + 0.5); /* to [-pi, pi] */
    x2 = x * x;
    for (n = 2; n <= 28; n += 2) {
        term *= -x2 / (qb_real)(n * (n - 1));
        sum += term;
    }
    return sum;
}

int32_t qb_tilt_cdeg(int32_t phi_cdeg, int32_t theta_cdeg)
{
    const qb_real k = 3.14159265358979323846 / 18000.0;
    qb_real c = cos_series(phi_cdeg * k) * cos_series(theta_cdeg * k);
    c = c > 1.0 ? 1.0 : c < -1.0 ? -1.0 : c;
    return (int32_t)QM(lround)(QM(atan2)(QM(sqrt)(1.0 - c * c), c) / k);
}

void qb_modes_link_back(qb_modes_t *m, qb_real now)
{
    if (m->link_hold) {
        m->link_hold = 0;
        emit(m, QP_EVENT_CODE_LINK_REGAINED, (int32_t)QM(lround)((now - m->hold_since) * 1000.0));
    }
}

/* The two-stage link failsafe (docs/modes.md; fcb_sim.board.modes.ModeMachine._link): stage 1 after link.timeout_ms of
 * silence in a flight mode holds level with the lift it had (LINK_LOST); a frame back within link.failsafe_ms
 * gives control back (qb_modes_link_back); else stage 2, the PANIC (LINK_TIMEOUT). Returns whether to PANIC. */
static int link_failsafe(qb_modes_t *m, qb_real now, qb_real silent)
{
    int timed_out = silent > m->link_timeout_s, flying = qb_modes_flying(m);
    if (!timed_out) {
        qb_modes_link_back(m, now);
    } else if (flying && silent <= m->link_timeout_s + m->link_failsafe_s) {
        if (!m->link_hold) {
            m->hold_lift = qb_modes_lift(m);
            m->hold_since = now;
            m->link_hold = 1;
            emit(m, QP_EVENT_CODE_LINK_LOST, (int32_t)(silent * 1000.0));
        }
        timed_out = 0; /* the guard runs: the timeout proper is stage 2's */
    } else if (!m->link_timed_out || m->link_hold) {
        emit(m, QP_EVENT_CODE_LINK_TIMEOUT, (int32_t)(silent * 1000.0));
    }
    m->link_timed_out = (uint8_t)(timed_out || m->link_hold);
    return timed_out && flying;
}

void qb_modes_supervise(qb_modes_t *m, qb_real now, qb_real link_silent_s, int32_t battery, int32_t phi_cdeg,
                        int32_t theta_cdeg)
{
    int panic_now;
    int32_t tilt;
    m->now = now;
    if (battery >= 0)
        m->battery = battery;
    panic_now = link_failsafe(m, now, link_silent_s);
    if (m->battery >= 0 && m->battery < QP_BATTERY_LOW) {
        if (!m->low_battery_set) {
            m->low_battery_since = now;
            m->low_battery_set = 1;
        }
    } else {
        m->low_battery_set = 0;
    }
    if (!qb_modes_flying(m))
        return;
    if (panic_now) {
        qb_modes_panic(m, now);
        return;
    }
    if (m->low_battery_set && now - m->low_battery_since >= LOW_BATTERY_HOLD_S) {
        emit(m, QP_EVENT_CODE_LOW_BATTERY, m->battery);
        m->battery_low_latched = 1;
        qb_modes_panic(m, now);
        return;
    }
    tilt = qb_tilt_cdeg(phi_cdeg, theta_cdeg);
    if (tilt > TILT_LIMIT_CDEG) {
        emit(m, QP_EVENT_CODE_TILT_LIMIT, tilt);
        qb_modes_panic(m, now);
    }
}
