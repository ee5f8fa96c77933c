/* qb_test.c: the C board's own unit tests, built with ASan and UBSan (make -C firmware board-test). A stub HAL
 * (a level craft on the floor, or hovering, with seeded noise) stands in for the hardware. Exit status 0 when
 * every check passes; each failure prints one line. The tests a team reuses for its own board (docs/firmware.md).
 */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hal.h"
#include "qb_board.h"

static int failures;
#define CHECK(cond)                                                                                                \
    do {                                                                                                           \
        if (!(cond)) {                                                                                             \
            failures++;                                                                                            \
            printf("FAIL %s:%d: %s\n", __FILE__, __LINE__, #cond);                                                 \
        }                                                                                                          \
    } while (0)

/* --- the stub HAL ----------------------------------------------------------------------------------------- */

static uint64_t t_us;
static uint32_t rng = 12345u;
static uint8_t rx[4096];
static size_t rx_len;
static uint8_t tx[1 << 16];
static size_t tx_len;
static uint16_t motors[4];
static uint16_t battery = 1180;

static int noise(int amp)
{
    rng = rng * 1103515245u + 12345u;
    return (int)((rng >> 16) % (uint32_t)(2 * amp + 1)) - amp;
}

static uint32_t read_cost_us; /* each reading of the clock moves it on: tasks that take time (the profile) */

uint64_t hal_time_us(void)
{
    uint64_t t = t_us;
    t_us += read_cost_us;
    return t;
}

size_t hal_uart_read(uint8_t *buf, size_t cap)
{
    size_t n = rx_len < cap ? rx_len : cap;
    memcpy(buf, rx, n);
    memmove(rx, rx + n, rx_len - n);
    rx_len -= n;
    return n;
}

size_t hal_uart_write(const uint8_t *data, size_t len)
{
    if (tx_len + len > sizeof tx)
        tx_len = 0; /* the tests read what they need; older bytes go */
    memcpy(tx + tx_len, data, len);
    tx_len += len;
    return len;
}

uint32_t hal_uart_dropped(void) { return 0; }

void hal_imu_read(int16_t out[6])
{
    int i;
    for (i = 0; i < 3; i++)
        out[i] = (int16_t)(20 + noise(15));
    out[3] = (int16_t)noise(40);
    out[4] = (int16_t)noise(40);
    out[5] = (int16_t)(16384 + noise(60));
}

int hal_dmp_read(float q[4])
{
    q[0] = 1.0f;
    q[1] = 0.001f * (float)noise(5);
    q[2] = 0.001f * (float)noise(5);
    q[3] = 0.0f;
    return (t_us / 5000u) % 2 == 0;
}

void hal_baro_read(int32_t *p, int32_t *temp)
{
    *p = 101325 + noise(2);
    *temp = 2500;
}

uint16_t hal_battery_read(void) { return battery; }
void hal_motors_set(const uint16_t ae[4]) { memcpy(motors, ae, sizeof motors); }
int32_t hal_impact_mm_s(void) { return 0; }

static uint8_t flash[QB_LOG_BYTES]; /* NOR: erased 0xFF, programming ANDs */

int hal_flash_write(uint32_t addr, const uint8_t *data, size_t len)
{
    size_t i;
    if (addr > sizeof flash || len > sizeof flash - addr)
        return -1;
    for (i = 0; i < len; i++)
        flash[addr + i] &= data[i];
    return 0;
}

int hal_flash_read(uint32_t addr, uint8_t *data, size_t len)
{
    if (addr > sizeof flash || len > sizeof flash - addr)
        return -1;
    memcpy(data, flash + addr, len);
    return 0;
}

int hal_flash_erase(uint32_t addr, size_t len)
{
    if (addr > sizeof flash || len > sizeof flash - addr)
        return -1;
    memset(flash + addr, 0xFF, len);
    return 0;
}

/* --- helpers ---------------------------------------------------------------------------------------------- */

static qb_board_t board;
static qp_encoder_t pc;
static uint8_t cmd_id;

static void run_until(uint64_t until)
{
    while (qb_next_event_us(&board) < until) {
        t_us = qb_next_event_us(&board) > t_us ? qb_next_event_us(&board) : t_us;
        qb_poll(&board);
    }
    t_us = until > t_us ? until : t_us;
}

static void put(const uint8_t *frame, size_t n)
{
    memcpy(rx + rx_len, frame, n);
    rx_len += n;
    qb_poll(&board);
}

static void joystick(int16_t lift, int16_t roll)
{
    qp_joystick_t js = {roll, 0, 0, lift, 0};
    uint8_t f[QP_MAX_FRAME];
    put(f, qp_encode_joystick(&pc, &js, f));
}

static int32_t ack_value; /* the value of the last Ack command() read */

/* The status of the Ack to a command (the last Ack the board sent). */
static int command(uint8_t op, int32_t arg)
{
    qp_command_t c;
    qp_decoder_t dec;
    qp_packet_t pkt;
    uint8_t f[QP_MAX_FRAME];
    size_t i;
    int status = -1;
    c.cmd_id = ++cmd_id;
    c.op = op;
    c.arg = arg;
    tx_len = 0;
    put(f, qp_encode_command(&pc, &c, f));
    qp_decoder_init(&dec);
    for (i = 0; i < tx_len; i++) {
        if (qp_decode_byte(&dec, tx[i], &pkt) && pkt.type == QP_TYPE_ACK && pkt.u.ack.cmd_id == cmd_id) {
            status = pkt.u.ack.status;
            ack_value = pkt.u.ack.value;
        }
    }
    return status;
}

static void boot(void)
{
    qb_config_t cfg;
    t_us = 0;
    read_cost_us = 0;
    rx_len = tx_len = 0;
    memset(flash, 0xFF, sizeof flash);
    battery = 1180;
    memset(&pc, 0, sizeof pc);
    qb_config_default(&cfg);
    qb_init(&board, &cfg);
}

/* --- tests ------------------------------------------------------------------------------------------------ */

static void test_isqrt(void)
{
    uint32_t x;
    for (x = 0; x <= 1000000u; x++) {
        uint32_t r = qb_isqrt(x), f = (uint32_t)floor(sqrt((double)x));
        CHECK(r + 1 >= f && r <= f + 1);
        if (!(r + 1 >= f && r <= f + 1))
            break;
    }
}

static void test_mix(void)
{
    uint16_t out[4];
    qb_mix(-4 * 400 * 400, 0.0, 0.0, 0.0, 1, out);
    CHECK(out[0] == 400 && out[1] == 400 && out[2] == 400 && out[3] == 400);
    qb_mix(-4 * 400 * 400, 20000.0, 0.0, 0.0, 1, out); /* positive roll moment: left motor up, right down */
    CHECK(out[3] > 400 && out[1] < 400 && out[0] == out[2]);
    qb_mix(0, 0.0, 0.0, 0.0, 1, out); /* armed: idle */
    CHECK(out[0] == 150);
    qb_mix(-2000000000, 0.0, 0.0, 0.0, 0, out);
    CHECK(out[0] == 1000);
    qb_mix(2000000000, -1e12, 1e12, 1e12, 0, out); /* absurd inputs saturate, never overflow */
    CHECK(out[0] <= 1000 && out[1] <= 1000);
}

static void test_ikf_finds_a_tilt_at_rest(void)
{
    qb_ikf_t f;
    qb_real e[3];
    const qb_real g = 9.81, phi = 10.0 * 3.14159265358979 / 180.0;
    int i;
    qb_ikf_reset(&f);
    for (i = 0; i < 2000; i++) /* 5 s at 400 Hz, rolled 10 degrees, a small gyro bias */
        qb_ikf_update(&f, 0.002, -0.001, 0.0005, 0.0, g * sin(phi), g * cos(phi), 0.0025);
    qb_ikf_angles(&f, e);
    CHECK(fabs(e[0] - phi) < 0.01 && fabs(e[1]) < 0.01);
    qb_ikf_update(&f, 1e9, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0025); /* absurd samples saturate, never overflow */
    qb_ikf_update(&f, 0.0, 0.0, 0.0, 0.0, 0.0, 9.81, -1.0);
    qb_ikf_angles(&f, e);
    CHECK(e[0] == e[0]);
}

static void test_guards(void)
{
    boot();
    run_until(200000);
    CHECK(command(QP_OP_MODE, QP_MODE_FULL) == QP_NAK_NOT_CALIBRATED);
    joystick(5000, 0);
    CHECK(command(QP_OP_MODE, QP_MODE_MANUAL) == QP_NAK_LIFT_NOT_ZERO);
    joystick(0, 5000);
    CHECK(command(QP_OP_MODE, QP_MODE_CALIBRATION) == QP_NAK_STICKS_NOT_NEUTRAL);
    joystick(0, 0);
    CHECK(command(QP_OP_MODE, 9) == QP_NAK_BAD_ARGUMENT);
    CHECK(command(QP_OP_MODE, -1) == QP_NAK_BAD_ARGUMENT);
    CHECK(command(99, 0) == QP_NAK_UNKNOWN_COMMAND);
    CHECK(command(QP_OP_MODE, QP_MODE_CALIBRATION) == QP_NAK_OK);
    run_until(1400000);
    CHECK(board.modes.mode == QP_MODE_SAFE && board.modes.calibrated);
    CHECK(command(QP_OP_MODE, QP_MODE_FULL) == QP_NAK_OK);
    CHECK(command(QP_OP_MODE, QP_MODE_MANUAL) == QP_NAK_INVALID_TRANSITION);
    joystick(9000, 0);
    CHECK(command(QP_OP_MODE, QP_MODE_SAFE) == QP_NAK_LIFT_NOT_ZERO);
    CHECK(command(QP_OP_MODE, QP_MODE_HEIGHT) == QP_NAK_OK);
    CHECK(command(QP_OP_MODE, QP_MODE_PANIC) == QP_NAK_OK);
    CHECK(command(QP_OP_MODE, QP_MODE_MANUAL) == QP_NAK_PANIC_ACTIVE);
    run_until(t_us + 400000000);
    joystick(0, 0);
    CHECK(board.modes.mode == QP_MODE_SAFE && command(QP_OP_MODE, QP_MODE_RAW) == QP_NAK_OK && board.raw_path == 0);
    run_until(t_us + 20000); /* the control step switches to the 400 Hz path */
    CHECK(board.raw_path == 1 && command(QP_OP_MODE, QP_MODE_HEIGHT) == QP_NAK_OK);
    CHECK(command(QP_OP_MODE, QP_MODE_FULL) == QP_NAK_INVALID_TRANSITION);
    CHECK(command(QP_OP_SET_PARAM, (QP_PARAM_ATTITUDE_FILTER << 24) | 0) == QP_NAK_NOT_IN_SAFE);
}

static void test_link_loss_and_panic_end_in_safe(void)
{
    uint64_t t;
    boot();
    joystick(0, 0);
    CHECK(command(QP_OP_MODE, QP_MODE_MANUAL) == QP_NAK_OK);
    for (t = 100000; t < 1000000; t += 100000) {
        joystick(8000, 0);
        run_until(t);
    }
    CHECK(board.modes.mode == QP_MODE_MANUAL && motors[0] > 150);
    run_until(1700000); /* silence: stage 1 holds level with the lift it had */
    CHECK(board.modes.mode == QP_MODE_MANUAL && board.modes.link_hold && board.modes.hold_lift == 8000);
    joystick(8000, 0); /* a frame back within link.failsafe_ms: control again */
    CHECK(!board.modes.link_hold && board.modes.mode == QP_MODE_MANUAL);
    CHECK(command(QP_OP_SET_PARAM, (QP_PARAM_LINK_FAILSAFE_MS << 24) | 2000) == QP_NAK_ONLY_SHORTER_IN_FLIGHT);
    CHECK(command(QP_OP_SET_PARAM, (QP_PARAM_LINK_FAILSAFE_MS << 24) | 500) == QP_NAK_OK);
    run_until(3000000); /* silence past both stages: PANIC */
    CHECK(board.modes.mode == QP_MODE_PANIC);
    run_until(400000000); /* the descent times out, the ramp ends, SAFE by itself */
    CHECK(board.modes.mode == QP_MODE_SAFE && motors[0] == 0);
}

static void test_low_battery(void)
{
    boot();
    joystick(0, 0);
    CHECK(command(QP_OP_MODE, QP_MODE_MANUAL) == QP_NAK_OK);
    battery = 1000;
    joystick(1000, 0);
    run_until(450000);
    CHECK(board.modes.mode == QP_MODE_PANIC && board.modes.battery_low_latched);
}

static void test_params(void)
{
    int i;
    boot();
    for (i = 0; i < QB_PARAM_COUNT; i++) {
        const qb_param_spec_t *s = &QB_PARAMS[i];
        CHECK(qb_param_get(&board, s->id) == s->def);
        CHECK(qb_param_set(&board, s->id, s->hi + 1, 1) == QP_NAK_OUT_OF_RANGE);
        CHECK(qb_param_set(&board, s->id, s->lo - 1, 1) == QP_NAK_OUT_OF_RANGE);
    }
    CHECK(qb_param_set(&board, 0, 0, 1) == QP_NAK_UNKNOWN_PARAM);
    CHECK(qb_param_set(&board, QB_PARAM_MAX_ID + 1, 0, 1) == QP_NAK_UNKNOWN_PARAM);
    CHECK(qb_param_set(&board, QP_PARAM_P1, 5000, 1) == QP_NAK_OK && qb_param_get(&board, QP_PARAM_P1) == 5000);
    CHECK(command(QP_OP_GAIN_P1, 2) == QP_NAK_OK && qb_param_get(&board, QP_PARAM_P1) == 6000);
    CHECK(command(QP_OP_GAIN_P1, -1000) == QP_NAK_OK && qb_param_get(&board, QP_PARAM_P1) == 0);
    CHECK(command(QP_OP_SET_PARAM, (QP_PARAM_TRIM_STEP << 24) | 100) == QP_NAK_OK);
    CHECK(command(QP_OP_PARAM_LIST, 0) == QP_NAK_OK);
    CHECK(!qb_rx_discard(&board, 1000)); /* bounded: the queue is kept */
    CHECK(command(QP_OP_SET_PARAM, (QP_PARAM_QUEUE_RULE << 24) | QB_QUEUE_RULE_DISCARD_20) == QP_NAK_OK);
    CHECK(qb_rx_discard(&board, QB_QUEUE_DISCARD_FRAMES) && !qb_rx_discard(&board, QB_QUEUE_DISCARD_FRAMES - 1));
    CHECK(command(QP_OP_LOG_START, 0) == QP_NAK_OK);
}

/* What PARAM_GET answers (the Ack's value), or INT32_MIN when refused. */
static int32_t param_get(int id)
{
    return command(QP_OP_PARAM_GET, id) == QP_NAK_OK ? ack_value : INT32_MIN;
}

static int32_t set_param_arg(int id, int32_t raw)
{
    return (int32_t)(((uint32_t)id << 24) | ((uint32_t)raw & 0xFFFFFFu));
}

/* One write of ``raw`` to parameter ``s`` by ``path`` (0 SET_PARAM, 1 a preset at boot: every guard but the
 * mode's): in range it is taken (or refused with the board's reason, the value unchanged), out of range it is
 * OUT_OF_RANGE and changes nothing; PARAM_GET always answers a value inside the table. */
static void write_checked(const qb_param_spec_t *s, int path, int32_t raw)
{
    int32_t before = param_get(s->id), after;
    int status = path == 0 ? command(QP_OP_SET_PARAM, set_param_arg(s->id, raw))
                           : qb_param_set(&board, s->id, raw, 0);
    after = param_get(s->id);
    CHECK(after >= s->lo && after <= s->hi);
    if (raw < s->lo || raw > s->hi) {
        CHECK(status == QP_NAK_OUT_OF_RANGE && after == before);
    } else if (status == QP_NAK_OK) {
        CHECK(after == raw);
    } else { /* this board's own refusals (qb_params.c), never a silent change */
        CHECK((status == QP_NAK_NOT_IMPLEMENTED || status == QP_NAK_BAD_ARGUMENT || status == QP_NAK_PARAM_RULE) &&
              after == before);
    }
}

/* Every parameter's limits through every path: SET_PARAM, a preset (qbh_set_param's path), and for the gains their
 * keys: bursts past both ends (the finding of issue 37: P2 +100,000 presses read 501111, yaw P +1e9 wrapped) give
 * the table's ends, in SAFE and in flight. */
static void test_param_limits_every_path(void)
{
    static const int32_t bursts[] = {100000, 1000000, 1000000000, INT32_MAX, -100000, -1000000000, INT32_MIN};
    int i, path, k, flying;
    for (flying = 0; flying <= 1; flying++) {
        boot();
        joystick(0, 0);
        if (flying) {
            CHECK(command(QP_OP_MODE, QP_MODE_MANUAL) == QP_NAK_OK);
            joystick(6000, 0);
        }
        for (i = 0; i < QB_PARAM_COUNT; i++) {
            const qb_param_spec_t *s = &QB_PARAMS[i];
            for (path = 0; path < 2; path++) {
                const int32_t raws[] = {s->hi + 1, s->lo - 1, 0x7FFFFF, -0x800000, s->lo, s->hi, s->def};
                for (k = 0; k < (int)(sizeof raws / sizeof raws[0]); k++) {
                    if (flying && path == 0 && (!s->in_flight || s->shorter_in_flight)) {
                        int status = command(QP_OP_SET_PARAM, set_param_arg(s->id, raws[k]));
                        CHECK(status != QP_NAK_OK || !s->shorter_in_flight || raws[k] <= param_get(s->id));
                        CHECK(param_get(s->id) >= s->lo && param_get(s->id) <= s->hi);
                        continue;
                    }
                    write_checked(s, path, raws[k]);
                }
            }
        }
        for (i = 0; i < 5; i++) { /* the gain keys */
            const qb_param_spec_t *s = qb_param_spec(QP_PARAM_YAW_P + i);
            for (k = 0; k < (int)(sizeof bursts / sizeof bursts[0]); k++) {
                int32_t end = bursts[k] > 0 ? s->hi : s->lo, milli;
                CHECK(command((uint8_t)(QP_OP_GAIN_YAW_P + i), bursts[k]) == QP_NAK_OK);
                milli = ack_value; /* the gain x 1000 */
                CHECK(param_get(s->id) == end && milli == (int32_t)lround(end * s->scale * 1000.0));
                if (param_get(s->id) != end)
                    printf("  gain %d after %ld presses: raw %ld, not %ld\n", s->id, (long)bursts[k],
                           (long)param_get(s->id), (long)end);
            }
            CHECK(command((uint8_t)(QP_OP_GAIN_YAW_P + i), 0) == QP_NAK_OK && param_get(s->id) == s->lo);
        }
        CHECK(board.modes.mode == (flying ? QP_MODE_MANUAL : QP_MODE_SAFE));
    }
    /* the finding's figures, one by one from the defaults */
    boot();
    CHECK(command(QP_OP_GAIN_P2, 100000) == QP_NAK_OK && ack_value == 1000000 && param_get(QP_PARAM_P2) == 100000);
    CHECK(command(QP_OP_GAIN_P1, 1000000) == QP_NAK_OK && ack_value == 10000 && param_get(QP_PARAM_P1) == 100000);
    CHECK(command(QP_OP_GAIN_YAW_P, 1000000000) == QP_NAK_OK && param_get(QP_PARAM_YAW_P) == 500000);
    CHECK(board.core.g.p2 == 1000.0 && board.core.g.p1 == 10.0 && board.core.g.yaw_p == 5000.0);
}

/* The profile's arithmetic (qb_prof.c): mean, percentiles from the histogram (never below the true one, at most
 * 19 % above), the period, the CPU load, a control period past WCET99 a miss. */
static void test_profile(void)
{
    qb_prof_t p;
    qp_profile_t out;
    uint64_t t = 0;
    int i;
    memset(&p, 0, sizeof p);
    qb_prof_reset(&p, 0);
    for (i = 0; i < 1000; i++, t += 5000)
        qb_prof_ran(&p, QB_T_CONTROL, t, i % 200 < 199 ? 100u : 1001u);
    qb_prof_packet(&p, QB_T_CONTROL, &out);
    CHECK(out.task == QB_T_CONTROL && out.mean_us == 105 && out.period_us == 5000);
    CHECK(out.p99_us >= 100 && out.p99_us <= 119);   /* rank 990 of 1000 (Python's sorted(d)[int(0.99 n)]): 100 us */
    CHECK(out.p999_us >= 1001 && out.p999_us <= 1191); /* rank 999: 1001 us */
    CHECK(qb_prof_load(&p, t) == 2); /* 104.5 ms busy in 5 s */
    CHECK(!qb_prof_control_period(&p, 0, 5000) && qb_prof_control_period(&p, 0, 5974));
    CHECK(qb_prof_control_period(&p, 1, 2987) && !qb_prof_control_period(&p, 1, 2986));
    qb_prof_packet(&p, QB_T_CONTROL, &out);
    CHECK(out.misses == 2);
    for (i = 0; i < 200000; i++) /* a bucket past 65535 counts: halved, never wrapped */
        qb_prof_ran(&p, QB_T_PARSE, (uint64_t)i * 10u, 7u);
    qb_prof_packet(&p, QB_T_PARSE, &out);
    CHECK(out.p99_us == 7 && out.mean_us == 7 && out.period_us == 10);
    qb_prof_ran(&p, QB_T_HEARTBEAT, 1000, 1);
    CHECK(qb_prof_ran(&p, QB_T_HEARTBEAT, 990, 1) == 0); /* a clock that steps back: a period of 0, not 2^32 */
    CHECK(qb_prof_ran(&p, QB_T_HEARTBEAT, 1500, 1) == 500);
    qb_prof_ran(&p, QB_T_BARO, 0, 0xFFFFFFFFu); /* absurd durations saturate */
    qb_prof_packet(&p, QB_T_BARO, &out);
    CHECK(out.mean_us == 0xFFFF && out.p99_us == 0xFFFF);
    boot();
    CHECK(command(QP_OP_PROFILE, 0) == QP_NAK_OK && ack_value == QB_TASKS);
}

/* Tasks that take time, measured by hal_time_us(): the Status packet's CPU load, the Profile packets' durations,
 * and control periods past the deadline said as DEADLINE_MISS while flying. */
static void test_profile_in_the_loop(void)
{
    qp_decoder_t dec;
    qp_packet_t pkt;
    size_t i;
    int load = -1, misses = -1, deadline_events = 0, ctl_mean = -1;
    boot();
    joystick(0, 0);
    CHECK(command(QP_OP_MODE, QP_MODE_MANUAL) == QP_NAK_OK);
    joystick(8000, 0);
    read_cost_us = 700; /* every task 700 us: a pass of sensor and control overruns the 5 ms tick now and then */
    tx_len = 0;
    run_until(t_us + 2000000);
    read_cost_us = 0;
    qp_decoder_init(&dec);
    for (i = 0; i < tx_len; i++) {
        if (!qp_decode_byte(&dec, tx[i], &pkt))
            continue;
        if (pkt.type == QP_TYPE_STATUS)
            load = pkt.u.status.cpu_load;
        if (pkt.type == QP_TYPE_EVENT && pkt.u.event.code == QP_EVENT_CODE_DEADLINE_MISS)
            deadline_events++;
    }
    command(QP_OP_PROFILE, 0); /* the Profile packets follow the Ack */
    qp_decoder_init(&dec);
    for (i = 0; i < tx_len; i++) {
        if (qp_decode_byte(&dec, tx[i], &pkt) && pkt.type == QP_TYPE_PROFILE && pkt.u.profile.task == QB_T_CONTROL) {
            misses = pkt.u.profile.misses;
            ctl_mean = pkt.u.profile.mean_us;
        }
    }
    CHECK(ctl_mean >= 690 && ctl_mean <= 700); /* the command's own passes ran with no cost */
    CHECK(misses > 0 && deadline_events == 1); /* at most one event in 10 s */
    CHECK(load >= 40 && load <= 100); /* sensor and control, 1.4 ms of every 5, and the rest */
    printf("  profile: control mean %d us, %d misses, cpu load %d %%\n", ctl_mean, misses, load);
}

/* The flash log under the sanitizers: int32's ends in every column (delta8's overload, Rice's escapes and
 * residuals past 32 bits), a log that fills (FULL, closed with its count), the commands' guards. */
static void test_log_extremes(void)
{
    qb_log_t l;
    int64_t row[QB_LOG_VARS];
    uint8_t chunk[QB_LOG_CHUNK];
    uint8_t scheme;
    int i, k;
    for (scheme = QB_SCHEME_DELTA8; scheme <= QB_SCHEME_RICE; scheme++) {
        memset(flash, 0xFF, sizeof flash);
        qb_log_init(&l, 4000u, scheme);
        CHECK(qb_log_start(&l) == QP_NAK_OK && l.state == QP_LOG_STATE_RECORDING);
        for (k = 0; k < 2000 && l.state == QP_LOG_STATE_RECORDING; k++) {
            for (i = 0; i < QB_LOG_VARS; i++)
                row[i] = (k + i) % 3 == 0 ? INT32_MIN : (k + i) % 3 == 1 ? INT32_MAX : (int64_t)noise(1000);
            qb_log_append(&l, row);
        }
        CHECK(l.state == QP_LOG_STATE_FULL && l.used <= 4000u && l.records > 10 && l.flash_errors == 0);
        CHECK(flash[0] == 'Q' && flash[1] == 'L' && flash[3] == scheme);
        CHECK((uint32_t)(flash[6] | flash[7] << 8 | flash[8] << 16 | (uint32_t)flash[9] << 24) == l.records);
        CHECK(qb_log_start(&l) == QP_NAK_LOG_FULL);
        qb_log_chunk(&l, qb_log_chunks(&l) - 1u, chunk);
        qb_log_chunk(&l, 100000u, chunk); /* past the end: erased bytes */
        CHECK(chunk[0] == 0xFF && chunk[QB_LOG_CHUNK - 1] == 0xFF);
        CHECK(qb_log_reset(&l, 0) == QP_NAK_NOT_IN_SAFE && qb_log_reset(&l, 1) == QP_NAK_OK && l.used == 0);
        CHECK(flash[0] == 0xFF && qb_log_crc32(&l) == 0u);
    }
    boot();
    CHECK(command(QP_OP_LOG_DOWNLOAD, 0) == QP_NAK_LOG_EMPTY);
    CHECK(command(QP_OP_LOG_START, 0) == QP_NAK_OK);
    run_until(t_us + 300000);
    CHECK(command(QP_OP_LOG_DOWNLOAD, 0) == QP_NAK_LOG_BUSY);
    CHECK(command(QP_OP_SET_PARAM, (QP_PARAM_LOG_SCHEME << 24) | QB_SCHEME_DELTA8) == QP_NAK_LOG_BUSY);
    CHECK(command(QP_OP_LOG_STOP, 0) == QP_NAK_OK && board.log.records > 50);
    CHECK(command(QP_OP_LOG_DOWNLOAD, -1) == QP_NAK_BAD_ARGUMENT && ack_value == (int32_t)qb_log_chunks(&board.log));
    CHECK(command(QP_OP_LOG_DOWNLOAD, 0) == QP_NAK_OK && board.log.dl_active);
    CHECK(command(QP_OP_LOG_RESET, 0) == QP_NAK_LOG_BUSY);
    run_until(t_us + 2000000);
    CHECK(!board.log.dl_active && board.log.dl_sent == qb_log_chunks(&board.log));
    CHECK(command(QP_OP_LOG_RESET, 0) == QP_NAK_OK && board.log.used == 0);
}

static void test_garbage_never_hurts(void)
{
    int i, j;
    boot();
    for (i = 0; i < 2000; i++) {
        uint8_t junk[97];
        for (j = 0; j < (int)sizeof junk; j++)
            junk[j] = (uint8_t)noise(200);
        put(junk, sizeof junk);
        run_until(t_us + 1000);
    }
    for (i = 0; i < 300; i++) { /* commands with any op and arg */
        command((uint8_t)noise(30), noise(1 << 20) * 1024);
        run_until(t_us + 2500);
    }
    CHECK(board.modes.mode == QP_MODE_SAFE || board.modes.mode == QP_MODE_PANIC);
}

int main(void)
{
    test_isqrt();
    test_mix();
    test_ikf_finds_a_tilt_at_rest();
    test_guards();
    test_link_loss_and_panic_end_in_safe();
    test_low_battery();
    test_params();
    test_param_limits_every_path();
    test_profile();
    test_profile_in_the_loop();
    test_log_extremes();
    test_garbage_never_hurts();
    printf("qb_test: %s (%d failure%s)\n", failures ? "FAILED" : "ok", failures, failures == 1 ? "" : "s");
    return failures ? 1 : 0;
}
