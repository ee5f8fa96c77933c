/* qb_board.c: the main loop, its tasks, commands and telemetry: fcb_sim/board/board.py, scheduler.py, commands.py
 * and telemetry.py in C (qb_board.h says what is in and what is not yet). Tasks take no board time here: the
 * host backend runs them at the instant their timer expires (lockstep with the physics). */
#include <math.h>
#include <string.h>

#include "hal.h"
#include "qb_board.h"

static const uint8_t RR_ORDER[] = {QB_T_PARSE, QB_T_BARO, QB_T_TELEMETRY, QB_T_HEARTBEAT, QB_T_SENSOR,
                                   QB_T_CONTROL, QB_T_LOGGING};
#define RR_N (sizeof RR_ORDER / sizeof RR_ORDER[0])

/* Microseconds to seconds. In float (the M0) by whole seconds and the rest: a 64-bit integer to float conversion
 * would link the soft double routines, and a float of the whole count would lose the microseconds. */
static qb_real us_to_s(uint64_t us)
{
#ifdef QB_FLOAT
    return (qb_real)(uint32_t)(us / 1000000u) + (qb_real)(uint32_t)(us % 1000000u) * 1e-6;
#else
    return (qb_real)us / 1e6;
#endif
}

static qb_real now_s(const qb_board_t *b)
{
    return us_to_s(b->now);
}

/* --- timers on the 32768 Hz RTC (fcb_sim/board/timing.py: rtc_ticks, rtc_us, us_to_ticks) ----------------------- */

static uint64_t rtc_ticks(uint32_t period_us)
{
    uint64_t t = ((uint64_t)period_us * QB_RTC_HZ + 500000u) / 1000000u;
    return t ? t : 1;
}

static uint64_t rtc_us(uint64_t ticks)
{
    return (ticks * 1000000u + QB_RTC_HZ - 1) / QB_RTC_HZ;
}

static uint32_t timer_period(const qb_board_t *b, int timer)
{
    uint32_t hz;
    switch (timer) {
    case QB_TM_SENSOR:
        return b->raw_path ? QB_SENSOR_RAW_US : QB_SENSOR_DMP_US;
    case QB_TM_BARO:
        return QB_BARO_PERIOD_US;
    case QB_TM_HEARTBEAT: /* link.heartbeat_ms */
        return (uint32_t)b->heartbeat_ms * 1000u;
    default: /* link.telemetry_hz in its raw unit, 0.01 Hz; a log download rides it at its own pace */
        if (b->log.dl_active)
            return QB_DOWNLOAD_PERIOD_US;
        hz = b->telemetry_hz > 0 ? (uint32_t)b->telemetry_hz : 1u;
        return 100000000u / hz < 10000u ? 10000u : 100000000u / hz;
    }
}

static void fire_timers(qb_board_t *b)
{
    static const uint8_t TASK_OF[QB_TIMERS] = {QB_T_SENSOR, QB_T_BARO, QB_T_TELEMETRY, QB_T_HEARTBEAT};
    int i;
    for (i = 0; i < QB_TIMERS; i++) {
        if (b->now >= b->next_us[i]) {
            uint64_t period = rtc_ticks(timer_period(b, i)), now_tk = b->now * QB_RTC_HZ / 1000000u;
            uint64_t missed = now_tk >= b->next_tk[i] ? (now_tk - b->next_tk[i]) / period : 0;
            b->flags[TASK_OF[i]] = 1;
            b->next_tk[i] += (missed + 1) * period;
            b->next_us[i] = rtc_us(b->next_tk[i]);
        }
    }
}

uint64_t qb_next_event_us(const qb_board_t *b)
{
    uint64_t t = b->next_us[0];
    int i;
    for (i = 1; i < QB_TIMERS; i++)
        t = b->next_us[i] < t ? b->next_us[i] : t;
    return t;
}

/* --- sending ------------------------------------------------------------------------------------------------ */

void qb_send(qb_board_t *b, const qp_packet_t *pkt)
{
    uint8_t frame[QP_MAX_FRAME];
    size_t n = qp_encode(&b->enc, pkt, frame);
    if (n && hal_uart_write(frame, n) != n)
        b->tx_dropped++;
}

void qb_send_event(qb_board_t *b, uint8_t code, int32_t arg)
{
    qp_packet_t p;
    p.type = QP_TYPE_EVENT;
    p.u.event.code = code;
    p.u.event.arg = arg;
    p.u.event.board_ms = (uint32_t)(b->now / 1000u);
    qb_send(b, &p);
}

static void send_hello(qb_board_t *b)
{
    qp_packet_t p;
    p.type = QP_TYPE_HELLO;
    p.u.hello.protocol = QP_PROTOCOL_VERSION;
    p.u.hello.role = QP_ROLE_BOARD;
    p.u.hello.major = QB_VERSION_MAJOR;
    p.u.hello.minor = QB_VERSION_MINOR;
    p.u.hello.board_id = b->cfg.board_id;
    qb_send(b, &p);
}

static void drain_mode_events(qb_board_t *b)
{
    qb_event_t ev;
    while (qb_modes_take_event(&b->modes, &ev))
        qb_send_event(b, ev.code, ev.arg);
}

static int16_t i16(qb_real v)
{
    qb_real r = QM(floor)(v + 0.5);
    return (int16_t)(r < -32768.0 ? -32768 : r > 32767.0 ? 32767 : r);
}

/* --- motors and the mode listener ---------------------------------------------------------------------------- */

static void set_motors(qb_board_t *b, const uint16_t ae[4])
{
    memcpy(b->ae, ae, sizeof b->ae);
    b->modes.motor_level = (ae[0] + ae[1] + ae[2] + ae[3]) / 4;
    hal_motors_set(ae);
}

/* The board's listener on the mode machine (fcb_sim.board.board.Board._on_mode_change). */
static void on_mode_change(void *ctx, uint8_t old_mode, uint8_t new_mode)
{
    qb_board_t *b = ctx;
    qb_modes_t *m = &b->modes;
    if (old_mode == QP_MODE_CALIBRATION && m->calibrated && m->counts[QB_CAL_GX] > 0) {
        qb_real gyro[3], accel[3], phi = 0.0, theta = 0.0, pressure = b->pressure;
        int i;
        for (i = 0; i < 3; i++) {
            gyro[i] = qb_modes_cal_mean(m, QB_CAL_GX + i);
            accel[i] = qb_modes_cal_mean(m, QB_CAL_AX + i);
        }
        if (m->counts[QB_CAL_DMP_PHI])
            phi = qb_modes_cal_mean(m, QB_CAL_DMP_PHI) / DMP_ANGLE_LSB;
        if (m->counts[QB_CAL_DMP_THETA])
            theta = qb_modes_cal_mean(m, QB_CAL_DMP_THETA) / DMP_ANGLE_LSB;
        if (m->counts[QB_CAL_PRESSURE])
            pressure = qb_modes_cal_mean(m, QB_CAL_PRESSURE);
        qb_flight_set_calibration(&b->core, gyro, accel, phi, theta, pressure);
    }
    if (new_mode != QP_MODE_SAFE && b->log.dl_active)
        qb_log_end_download(b);
    qb_flight_enter_mode(&b->core, new_mode, qb_modes_lift(m));
}

/* --- tasks ---------------------------------------------------------------------------------------------------- */

/* The sensor path to run (est.sensor_path): "auto" is RAW in RAW mode (and HEIGHT entered from RAW), else DMP.
 * A change restarts the sensor timer at the new rate. */
static void follow_sensor_path(qb_board_t *b)
{
    const qb_modes_t *m = &b->modes;
    uint8_t want = b->sensor_path == QB_SENSOR_PATH_RAW ||
                   (b->sensor_path == QB_SENSOR_PATH_AUTO &&
                    (m->mode == QP_MODE_RAW || (m->mode == QP_MODE_HEIGHT && m->height_base == QP_MODE_RAW)));
    if (want != b->raw_path) {
        b->raw_path = want;
        b->next_tk[QB_TM_SENSOR] = b->now * QB_RTC_HZ / 1000000u + rtc_ticks(timer_period(b, QB_TM_SENSOR));
        b->next_us[QB_TM_SENSOR] = rtc_us(b->next_tk[QB_TM_SENSOR]);
        b->sample_set = 0;
    }
}

static void task_sensor(qb_board_t *b)
{
    int16_t raw[6];
    float q[4];
    qb_real t = now_s(b), dt;
    int cal = b->modes.mode == QP_MODE_CALIBRATION, i;
    hal_imu_read(raw);
    dt = b->sample_set ? t - us_to_s(b->sample_t) : timer_period(b, QB_TM_SENSOR) / 1e6;
    b->sample_t = b->now;
    b->sample_set = 1;
    qb_flight_imu(&b->core, raw, dt);
    if (cal) {
        for (i = 0; i < 6; i++)
            qb_modes_cal_add(&b->modes, QB_CAL_GX + i, raw[i]);
    }
    if (!b->raw_path && hal_dmp_read(q)) { /* the DMP is read on the DMP path only */
        qb_flight_dmp(&b->core, q);
        if (cal) {
            qb_real e[3];
            qb_quaternion_to_euler(q[0], q[1], q[2], q[3], e);
            qb_modes_cal_add(&b->modes, QB_CAL_DMP_PHI, (int32_t)QM(lround)(e[0] * DMP_ANGLE_LSB));
            qb_modes_cal_add(&b->modes, QB_CAL_DMP_THETA, (int32_t)QM(lround)(-e[1] * DMP_ANGLE_LSB));
        }
    }
    b->flags[QB_T_CONTROL] = 1; /* data ready: control follows */
}

static void task_control(qb_board_t *b)
{
    qb_modes_t *m = &b->modes;
    qb_real t = now_s(b);
    int32_t impact = hal_impact_mm_s(), sticks[4], contact, drift;
    uint16_t ae[4];
    if (impact > 0)
        qb_modes_crash(m, t, impact);
    qb_modes_tick(m, t);
    if (m->mode == QP_MODE_PANIC) {
        if (b->core.panic_landed)
            qb_modes_panic_ground(m, t);
        b->core.panic_scale = qb_modes_panic_scale(m, t);
    }
    qb_modes_sticks(m, sticks);
    qb_flight_control(&b->core, m->mode, sticks, timer_period(b, QB_TM_SENSOR) / 1e6, ae);
    contact = qb_flight_pending_contact(&b->core);
    if (contact >= 0) /* a hard stop the accelerometer felt: the pilot sees it */
        qb_modes_event(m, QP_EVENT_CODE_CONTACT, contact);
    if (qb_flight_pending_heading_drift(&b->core, &drift)) /* the heading is relative: its drift since calibration */
        qb_modes_event(m, QP_EVENT_CODE_HEADING_DRIFT, drift);
    if (!qb_modes_motors_enabled(m))
        memset(ae, 0, sizeof ae);
    qb_motortest_apply(b, ae); /* qb_console.c: the bench motor test (SAFE only) */
    memcpy(b->sticks_used, sticks, sizeof b->sticks_used);
    b->sticks_set = 1;
    set_motors(b, ae);
    if (b->log.state == QP_LOG_STATE_RECORDING)
        b->flags[QB_T_LOGGING] = 1;
    follow_sensor_path(b);
}

static void task_baro(qb_board_t *b)
{
    qb_real dt = b->baro_set ? us_to_s(b->now - b->baro_t) : 0.05;
    hal_baro_read(&b->pressure, &b->temperature);
    b->battery = hal_battery_read();
    b->baro_t = b->now;
    b->baro_set = 1;
    qb_flight_baro(&b->core, b->pressure, dt);
    {
        qb_real sv = b->battery * 0.01 / QB_THRUST_V_REF; /* the thrust model scales the commands by the pack */
        b->core.hest.supply_sq = sv * sv;
    }
    b->modes.battery = b->battery;
    if (b->modes.mode == QP_MODE_CALIBRATION)
        qb_modes_cal_add(&b->modes, QB_CAL_PRESSURE, b->pressure);
}

void qb_starved(qb_board_t *b, uint64_t until_us, int slip)
{
    uint64_t lag;
    if (until_us <= b->now)
        return;
    lag = until_us - b->now;
    if (!slip) {
        if (b->n_deaf == QB_DEAF_SPANS) { /* the oldest span goes (silence is measured from the last frame on) */
            memmove(b->deaf[0], b->deaf[1], (QB_DEAF_SPANS - 1) * sizeof b->deaf[0]);
            b->n_deaf--;
        }
        b->deaf[b->n_deaf][0] = b->now;
        b->deaf[b->n_deaf][1] = until_us;
        b->n_deaf++;
    }
    b->lag_max_us = lag > b->lag_max_us ? lag : b->lag_max_us;
    if (b->lag_max_us < 100000u || b->now < b->lag_report_at)
        return;
    qb_send_event(b, QP_EVENT_CODE_SIM_LAG, (int32_t)(b->lag_max_us / 1000u));
    b->lag_max_us = 0;
    b->lag_report_at = b->now + 1000000u;
}

uint64_t qb_link_silent_us(qb_board_t *b)
{
    uint64_t last = b->last_frame_us, deaf = 0;
    uint8_t i, n = 0;
    if (!b->last_frame_set)
        return 0;
    for (i = 0; i < b->n_deaf; i++) {
        uint64_t lo = b->deaf[i][0] > last ? b->deaf[i][0] : last, hi = b->deaf[i][1] < b->now ? b->deaf[i][1] : b->now;
        if (b->deaf[i][1] <= last)
            continue; /* before the last frame: forgotten */
        if (hi > lo)
            deaf += hi - lo;
        b->deaf[n][0] = b->deaf[i][0];
        b->deaf[n][1] = b->deaf[i][1];
        n++;
    }
    b->n_deaf = n;
    return b->now - last - deaf;
}

static void task_heartbeat(qb_board_t *b)
{
    qp_packet_t p;
    int32_t att[3];
    uint32_t rtt = b->rtt_us / 100u;
    qb_real silent = us_to_s(qb_link_silent_us(b));
    b->heartbeats++;
    p.type = QP_TYPE_HEARTBEAT;
    p.u.heartbeat.counter = (uint16_t)b->heartbeats;
    p.u.heartbeat.board_ms = (uint32_t)(b->now / 1000u);
    p.u.heartbeat.rtt = (uint16_t)(b->hb_rtt_fresh ? (rtt > 0xFFFFu ? 0xFFFFu : rtt < 1u ? 1u : rtt) : 0u);
    qb_send(b, &p);
    b->hb_sent_counter = p.u.heartbeat.counter;
    b->hb_sent_us = b->now;
    b->hb_sent_set = 1;
    b->hb_rtt_fresh = 0;
    qb_flight_attitude_cdeg(&b->core, att);
    qb_modes_supervise(&b->modes, now_s(b), silent, b->battery, att[0], att[1]); /* the last ADC reading */
    drain_mode_events(b);
}

static int due(uint64_t *due_at, uint32_t period_us, uint64_t now)
{
    uint64_t next = *due_at + period_us, half = now > period_us / 2 ? now - period_us / 2 : 0;
    if (now < *due_at)
        return 0;
    *due_at = next > half ? next : half;
    return 1;
}

static uint16_t status_flags(const qb_board_t *b)
{
    const qb_modes_t *m = &b->modes;
    uint16_t f = 0;
    f |= m->calibrated ? QP_FLAG_CALIBRATED : 0u;
    f |= qb_modes_motors_enabled(m) ? QP_FLAG_ARMED : 0u;
    f |= (b->battery < QP_BATTERY_LOW || m->battery_low_latched) ? QP_FLAG_LOW_BATTERY : 0u;
    f |= m->link_timed_out ? QP_FLAG_LINK_TIMEOUT : 0u;
    f |= b->raw_path ? QP_FLAG_RAW_SENSORS : 0u;
    f |= b->fixed_point ? QP_FLAG_FIXED_POINT : 0u;
    f |= b->scheduler == QB_SCHEDULER_PRIORITY ? QP_FLAG_PRIORITY_SCHEDULER : 0u;
    f |= m->mode == QP_MODE_HEIGHT ? QP_FLAG_HEIGHT_HOLD : 0u;
    f |= m->crashed ? QP_FLAG_CRASHED : 0u;
    f |= b->mt.on ? QP_FLAG_MOTOR_TEST : 0u; /* qb_console.c */
    f |= !b->core.height_comp && qb_height_unsure(&b->core.hest) ? QP_FLAG_HEIGHT_UNSURE : 0u; /* Figure 10: never */
    return f;
}

static void send_status(qb_board_t *b)
{
    const qb_modes_t *m = &b->modes;
    qp_packet_t p;
    p.type = QP_TYPE_STATUS;
    p.u.status.flags = status_flags(b);
    p.u.status.trim_roll = (int16_t)m->trim_roll;
    p.u.status.trim_pitch = (int16_t)m->trim_pitch;
    p.u.status.trim_yaw = (int16_t)m->trim_yaw;
    p.u.status.trim_lift = (int16_t)m->trim_lift;
    p.u.status.cpu_load = qb_prof_load(&b->prof, b->now);
    p.u.status.log_fill = (uint8_t)((uint64_t)b->log.used * 100u / b->log.size > 100u
                                        ? 100u : (uint64_t)b->log.used * 100u / b->log.size);
    p.u.status.wireless = QP_WIRELESS_STATE_DISCONNECTED;
    qb_send(b, &p);
}

static void task_telemetry(qb_board_t *b)
{
    const qb_flight_t *fc = &b->core;
    qp_packet_t p;
    int32_t att[3];
    b->telemetry_runs++;
    drain_mode_events(b);
    if (b->log.dl_active) { /* log chunks instead of telemetry, a Status every tenth run */
        qb_log_download_step(b);
        if (b->telemetry_runs % 10u == 0u)
            send_status(b);
        return;
    }
    qb_flight_attitude_cdeg(fc, att);
    p.type = QP_TYPE_ATTITUDE;
    p.u.attitude.mode = b->modes.mode;
    p.u.attitude.phi = i16(att[0]);
    p.u.attitude.theta = i16(att[1]);
    p.u.attitude.psi = i16(att[2]);
    p.u.attitude.sp = i16(fc->sp);
    p.u.attitude.sq = i16(fc->sq);
    p.u.attitude.sr = i16(fc->sr);
    qb_send(b, &p);
    p.type = QP_TYPE_MOTION;
    p.u.motion.sax = i16(fc->sax);
    p.u.motion.say = i16(fc->say);
    p.u.motion.saz = i16(fc->saz);
    p.u.motion.ae1 = b->ae[0];
    p.u.motion.ae2 = b->ae[1];
    p.u.motion.ae3 = b->ae[2];
    p.u.motion.ae4 = b->ae[3];
    qb_send(b, &p);
    if (due(&b->height_due, HEIGHT_PERIOD_US, b->now)) {
        p.type = QP_TYPE_HEIGHT;
        p.u.height.pressure = (uint32_t)(b->pressure > 0 ? b->pressure : 0);
        p.u.height.height = i16(fc->height / 0.01);
        p.u.height.setpoint = i16(fc->setpoint / 0.01);
        p.u.height.vz = i16(fc->vz / 0.01);
        p.u.height.battery = b->battery;
        p.u.height.temperature = i16(b->temperature);
        qb_send(b, &p);
    }
    if (due(&b->status_due, STATUS_PERIOD_US, b->now)) {
        send_status(b);
        p.type = QP_TYPE_GAINS;
        p.u.gains.yaw_p = qp_half_from_float((float)fc->g.yaw_p);
        p.u.gains.p1 = qp_half_from_float((float)fc->g.p1);
        p.u.gains.p2 = qp_half_from_float((float)fc->g.p2);
        p.u.gains.height_p = qp_half_from_float((float)fc->g.height_p);
        p.u.gains.height_d = qp_half_from_float((float)fc->g.height_d);
        qb_send(b, &p);
    }
}

/* --- commands (fcb_sim/board/commands.py) ------------------------------------------------------------------------- */

typedef struct {
    uint8_t status;
    int32_t value;
    int after;      /* what follows the Ack: 0 nothing, 1 PARAM_CHANGED for after_param, 2 the parameter list,
                     * 3 the task profile, 4 the LogStatus, 5 a download's start, 6 HEIGHT_SETPOINT */
    int after_param;
} result_t;

static qb_real *gain_of(qb_board_t *b, int param)
{
    qb_gains_t *g = &b->core.g;
    switch (param) {
    case QP_PARAM_YAW_P: return &g->yaw_p;
    case QP_PARAM_P1: return &g->p1;
    case QP_PARAM_P2: return &g->p2;
    case QP_PARAM_HEIGHT_P: return &g->height_p;
    default: return &g->height_d;
    }
}

/* x (>= 0) to the nearest integer, a half to the even one, as Python's round(): no libm on the M0 for one call. */
static int round_half_even(qb_real x)
{
    qb_real v = x + 0.5;
    int q = (int)v;
    return ((qb_real)q == v && (q & 1)) ? q - 1 : q;
}

static result_t execute(qb_board_t *b, const qp_command_t *c)
{
    result_t r = {QP_NAK_OK, 0, 0, 0};
    qb_real t = now_s(b);
    switch (c->op) {
    case QP_OP_MODE:
        if (c->arg == QP_MODE_WIRELESS) {
            /* the handover: no radio on this board, so no phone is ever connected */
            r.status = b->modes.mode != QP_MODE_SAFE ? QP_NAK_NOT_IN_SAFE : QP_NAK_NO_BLE_CONNECTION;
            return r;
        }
        qb_modes_tick(&b->modes, t);
        r.status = qb_modes_request(&b->modes, c->arg, t);
        r.value = b->modes.mode;
        return r;
    case QP_OP_TRIM_LIFT:
        if (b->modes.mode == QP_MODE_HEIGHT) { /* the lift keys move HEIGHT's set point (commands.py _height_keys) */
            qb_real sp = qb_flight_move_setpoint(&b->core, (qb_real)c->arg * QP_HEIGHT_KEY_STEP_MM / 1000.0,
                                                 QP_HEIGHT_SETPOINT_MIN_MM / 1000.0, QP_HEIGHT_SETPOINT_MAX_MM / 1000.0);
            r.value = b->modes.trim_lift;
            r.after = 6;
            r.after_param = round_half_even(sp * 1000.0); /* Python's round() */
            return r;
        }
        /* fall through */
    case QP_OP_TRIM_ROLL:
    case QP_OP_TRIM_PITCH:
    case QP_OP_TRIM_YAW:
        r.value = qb_modes_adjust_trim(&b->modes, c->op - QP_OP_TRIM_LIFT, c->arg);
        return r;
    case QP_OP_GAIN_YAW_P:
    case QP_OP_GAIN_P1:
    case QP_OP_GAIN_P2:
    case QP_OP_GAIN_HEIGHT_P:
    case QP_OP_GAIN_HEIGHT_D: {
        /* arg presses of the table's step, kept inside the table's range, written by the same setter and guards as
         * SET_PARAM (fcb_sim's commands._gain): no key burst can push a gain past the table (issue 37) */
        int param = QP_PARAM_YAW_P + (c->op - QP_OP_GAIN_YAW_P);
        r.status = qb_param_set(b, param, qb_param_raw_clamped(qb_param_spec(param),
                                                               *gain_of(b, param) +
                                                                   (qb_real)c->arg * QB_PARAMS[param - 1].step), 1);
        if (r.status != QP_NAK_OK)
            return r;
        r.value = (int32_t)QM(lround)(*gain_of(b, param) * 1000.0);
        r.after = 1;
        r.after_param = param;
        return r;
    }
    case QP_OP_WIRELESS:
        if (c->arg == 1)
            r.status = b->modes.mode != QP_MODE_SAFE ? QP_NAK_NOT_IN_SAFE : QP_NAK_NO_BLE_CONNECTION;
        else if (c->arg != 0)
            r.status = QP_NAK_BAD_ARGUMENT;
        return r;
    case QP_OP_SET_PARAM: {
        int pid = (int)(((uint32_t)c->arg >> 24) & 0xFFu);
        int32_t raw = (int32_t)((uint32_t)c->arg & 0xFFFFFFu);
        if (raw > 0x7FFFFF)
            raw -= 0x1000000;
        r.status = qb_param_set(b, pid, raw, 1);
        r.value = qb_param_spec(pid) ? qb_param_get(b, pid) : 0;
        if (r.status == QP_NAK_PARAM_RULE) /* the Ack names the rule: its index in QB_RULES */
            r.value = qb_param_broken_rule(b, pid, raw);
        r.after = r.status == QP_NAK_OK;
        r.after_param = pid;
        return r;
    }
    case QP_OP_PARAM_GET:
        if (!qb_param_spec(c->arg))
            r.status = QP_NAK_UNKNOWN_PARAM;
        else
            r.value = qb_param_get(b, c->arg);
        return r;
    case QP_OP_PARAM_LIST:
        r.value = QB_PARAM_COUNT;
        r.after = 2;
        return r;
    case QP_OP_PROFILE: /* the Profile packets follow the Ack, one per task */
        r.value = QB_TASKS;
        r.after = 3;
        return r;
    case QP_OP_ACK_CRASH:
        r.status = qb_modes_ack_crash(&b->modes);
        return r;
    case QP_OP_MOTOR_TEST: /* qb_console.c: the bench motor test */
        r.status = qb_motortest_command(b, c->arg, &r.value);
        return r;
    case QP_OP_LOG_START: /* fcb_sim/board/commands.py's _log_* */
        if (b->log.dl_active) {
            r.status = QP_NAK_LOG_BUSY;
            return r;
        }
        r.status = qb_log_start(&b->log);
        if (r.status == QP_NAK_OK)
            b->log.full_reported = 0;
        r.value = (int32_t)b->log.used;
        return r;
    case QP_OP_LOG_STOP:
        r.status = qb_log_stop(&b->log);
        r.value = (int32_t)b->log.used;
        return r;
    case QP_OP_LOG_RESET:
        r.status = b->log.dl_active ? QP_NAK_LOG_BUSY : qb_log_reset(&b->log, b->modes.mode == QP_MODE_SAFE);
        return r;
    case QP_OP_LOG_STATUS:
        r.value = (int32_t)b->log.used;
        r.after = 4;
        return r;
    case QP_OP_LOG_DOWNLOAD:
        if (b->modes.mode != QP_MODE_SAFE)
            r.status = QP_NAK_NOT_IN_SAFE;
        else if (b->log.state == QP_LOG_STATE_RECORDING)
            r.status = QP_NAK_LOG_BUSY;
        else if (b->log.used == 0)
            r.status = QP_NAK_LOG_EMPTY;
        else if (c->arg < 0 || (uint32_t)c->arg >= qb_log_chunks(&b->log)) {
            r.status = QP_NAK_BAD_ARGUMENT;
            r.value = (int32_t)qb_log_chunks(&b->log);
        } else {
            r.value = (int32_t)qb_log_chunks(&b->log);
            r.after = 5;
        }
        return r;
    default:
        r.status = QP_NAK_UNKNOWN_COMMAND;
        return r;
    }
}

static void param_changed(qb_board_t *b, int param)
{
    int32_t raw = qb_param_get(b, param);
    qb_send_event(b, QP_EVENT_CODE_PARAM_CHANGED, (int32_t)(((uint32_t)param << 24) | ((uint32_t)raw & 0xFFFFFFu)));
}

static void handle_command(qb_board_t *b, const qp_command_t *c)
{
    qp_packet_t p;
    result_t r;
    int i;
    if (b->have_last && b->last_cmd.cmd_id == c->cmd_id && b->last_cmd.op == c->op && b->last_cmd.arg == c->arg &&
        b->now - b->last_cmd_us < QB_DEDUPE_US) {
        p.type = QP_TYPE_ACK; /* a retry: its first answer was lost; answered again, not done again */
        p.u.ack = b->last_ack;
        qb_send(b, &p);
        return;
    }
    r = execute(b, c);
    p.type = QP_TYPE_ACK;
    p.u.ack.cmd_id = c->cmd_id;
    p.u.ack.op = c->op;
    p.u.ack.status = r.status;
    p.u.ack.value = r.value;
    b->last_cmd = *c;
    b->last_ack = p.u.ack;
    b->last_cmd_us = b->now;
    b->have_last = 1;
    qb_send(b, &p);
    drain_mode_events(b);
    if (r.after == 1) {
        param_changed(b, r.after_param);
    } else if (r.after == 6) {
        qb_send_event(b, QP_EVENT_CODE_HEIGHT_SETPOINT, r.after_param);
    } else if (r.after == 4) {
        qb_log_send_status(b, b->log.state);
    } else if (r.after == 5) { /* the download begins: LogStatus DOWNLOADING, then the chunks (telemetry's turn) */
        qb_log_begin_download(b, (uint32_t)c->arg);
        if (b->next_us[QB_TM_TELEMETRY] > b->now + QB_DOWNLOAD_PERIOD_US) { /* under a slower telemetry rate */
            b->next_tk[QB_TM_TELEMETRY] = b->now * QB_RTC_HZ / 1000000u + rtc_ticks(QB_DOWNLOAD_PERIOD_US);
            b->next_us[QB_TM_TELEMETRY] = rtc_us(b->next_tk[QB_TM_TELEMETRY]);
        }
    } else if (r.after == 3) {
        for (i = 0; i < QB_TASKS; i++) {
            p.type = QP_TYPE_PROFILE;
            qb_prof_packet(&b->prof, i, &p.u.profile);
            qb_send(b, &p);
        }
    } else if (r.after == 2) {
        for (i = 0; i < QB_PARAM_COUNT; i++) {
            p.type = QP_TYPE_PARAM_VALUE;
            p.u.param_value.param = QB_PARAMS[i].id;
            p.u.param_value.value = qb_param_get(b, QB_PARAMS[i].id);
            p.u.param_value.index = (uint8_t)i;
            p.u.param_value.count = QB_PARAM_COUNT;
            qb_send(b, &p);
        }
    }
}

static void on_packet(void *ctx, const qp_packet_t *pkt)
{
    qb_board_t *b = ctx;
    b->last_frame_us = b->now;
    b->last_frame_set = 1;
    if (b->modes.link_hold) {
        qb_modes_link_back(&b->modes, now_s(b)); /* the failsafe's stage 1 ends with the first frame back */
        drain_mode_events(b);
    }
    switch (pkt->type) {
    case QP_TYPE_JOYSTICK:
        b->modes.js = pkt->u.joystick;
        if (pkt->u.joystick.buttons & QP_BUTTON_FIRE) {
            qb_modes_panic(&b->modes, now_s(b));
            drain_mode_events(b);
        }
        break;
    case QP_TYPE_COMMAND:
        handle_command(b, &pkt->u.command);
        break;
    case QP_TYPE_HEARTBEAT_ACK:
        if (b->hb_sent_set && pkt->u.heartbeat_ack.counter == b->hb_sent_counter) {
            b->rtt_us = (uint32_t)(b->now - b->hb_sent_us);
            b->hb_rtt_fresh = 1;
        }
        break;
    case QP_TYPE_HELLO:
        b->have_last = 0; /* a terminal (re)connected: its cmd_ids start afresh */
        qp_decoder_reset_sequence(&b->dec);
        send_hello(b);
        break;
    default:
        break;
    }
}

/* A changed stick moves the motors at once in the flight modes (docs/board.md, "Sticks to motors"). */
static void react(qb_board_t *b)
{
    int32_t sticks[4];
    uint16_t ae[4];
    uint8_t mode = b->modes.mode;
    if (!b->stick_reaction || !b->sticks_set)
        return;
    qb_modes_sticks(&b->modes, sticks);
    if (memcmp(sticks, b->sticks_used, sizeof sticks) == 0)
        return;
    if (!QP_IS_FLIGHT_MODE(mode) || mode != b->core.mode)
        return;
    qb_flight_control(&b->core, mode, sticks, 0.0, ae);
    set_motors(b, ae);
    memcpy(b->sticks_used, sticks, sizeof sticks);
}

int qb_rx_discard(const qb_board_t *b, uint32_t frames)
{
    return b->queue_rule == QB_QUEUE_RULE_DISCARD_20 && frames >= QB_QUEUE_DISCARD_FRAMES;
}

void qb_receive(qb_board_t *b, const uint8_t *data, size_t len)
{
    qp_decode(&b->dec, data, len, on_packet, b);
    react(b);
}

static void task_parse(qb_board_t *b)
{
    uint8_t buf[QB_PARSE_MAX_BYTES];
    size_t n = hal_uart_read(buf, sizeof buf);
    uint32_t dropped = hal_uart_dropped();
    if (dropped > b->overflow_reported && b->now >= b->overflow_report_at) {
        /* what was dropped since the last report, at most once per heartbeat period (a flood is one event) */
        qb_send_event(b, QP_EVENT_CODE_OVERFLOW, (int32_t)(dropped - b->overflow_reported));
        b->overflow_reported = dropped;
        b->overflow_report_at = b->now + QB_HEARTBEAT_PERIOD_US;
    }
    qb_receive(b, buf, n);
    if (n == sizeof buf)
        b->flags[QB_T_PARSE] = 1; /* more may be waiting */
}

/* --- the loop ------------------------------------------------------------------------------------------------ */

void qb_config_default(qb_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->board_id = 1;
    cfg->link_timeout_s = QB_PARAMS[QP_PARAM_LINK_TIMEOUT_MS - 1].def / 1000.0;
    cfg->link_failsafe_s = QB_PARAMS[QP_PARAM_LINK_FAILSAFE_MS - 1].def / 1000.0;
    cfg->phase_tk[QB_TM_SENSOR] = 0;
    cfg->phase_tk[QB_TM_BARO] = 547; /* unrelated phases, as independent hardware timers have */
    cfg->phase_tk[QB_TM_TELEMETRY] = 211;
    cfg->phase_tk[QB_TM_HEARTBEAT] = 1093;
    cfg->boot_hello = 1;
}

void qb_init(qb_board_t *b, const qb_config_t *cfg)
{
    int i;
    memset(b, 0, sizeof *b);
    b->cfg = *cfg;
    qb_flight_init(&b->core);
    qb_modes_init(&b->modes, cfg->link_timeout_s, b->core.panic_ae);
    b->modes.link_failsafe_s = cfg->link_failsafe_s;
    b->modes.on_change = on_mode_change;
    b->modes.ctx = b;
    qp_decoder_init(&b->dec);
    qb_log_init(&b->log, QB_LOG_BYTES, QB_PARAMS[QP_PARAM_LOG_SCHEME - 1].def);
    for (i = 0; i < QB_PARAM_COUNT; i++) {
        int id = QB_PARAMS[i].id;
        if (id != QP_PARAM_LINK_TIMEOUT_MS && id != QP_PARAM_LINK_FAILSAFE_MS)
            qb_param_set(b, id, QB_PARAMS[i].def, 0);
    }
    for (i = 0; i < QB_TIMERS; i++) {
        b->next_tk[i] = cfg->phase_tk[i];
        b->next_us[i] = rtc_us(b->next_tk[i]);
    }
    b->now = hal_time_us();
    b->battery = hal_battery_read();
    hal_baro_read(&b->pressure, &b->temperature);
    if (cfg->boot_hello) {
        send_hello(b);
        qb_send_event(b, QP_EVENT_CODE_BOOT, QP_PROTOCOL_VERSION);
    }
}

typedef void (*task_fn)(qb_board_t *b);

/* One task, timed by hal_time_us() (fcb_sim's Board.advance with Profiler.ran): its duration and period, and a
 * control period past the deadline said as DEADLINE_MISS while flying, at most every 10 s. */
static void run_task(qb_board_t *b, uint8_t task, task_fn fn)
{
    uint64_t start = hal_time_us(), end;
    uint32_t period;
    fn(b);
    end = hal_time_us();
    period = qb_prof_ran(&b->prof, task, start, (uint32_t)(end > start ? end - start : 0u));
    if (task == QB_T_CONTROL && period && qb_prof_control_period(&b->prof, b->raw_path, period) &&
        qb_modes_flying(&b->modes) && (!b->misses_reported || b->now - b->misses_reported_at >= 10000000u)) {
        b->misses_reported = 1;
        b->misses_reported_at = b->now;
        qb_send_event(b, QP_EVENT_CODE_DEADLINE_MISS, (int32_t)period);
    }
}

void qb_poll(qb_board_t *b)
{
    static const task_fn TASK[QB_TASKS] = {task_parse, task_sensor, task_control, task_baro, task_telemetry,
                                           task_heartbeat, qb_log_task};
    unsigned i;
    b->now = hal_time_us();
    fire_timers(b);
    b->flags[QB_T_PARSE] = 1; /* the UART queue is read at every pass (an empty read costs nothing) */
    for (;;) {
        int ran = 0;
        for (i = 0; i < RR_N && !ran; i++) {
            uint8_t task = RR_ORDER[(b->rr + i) % RR_N];
            if (b->flags[task]) {
                b->rr = (uint8_t)((b->rr + i + 1) % RR_N);
                b->flags[task] = 0;
                run_task(b, task, TASK[task]);
                ran = 1;
            }
        }
        if (!ran)
            break;
    }
}
