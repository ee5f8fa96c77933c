/* qb_board.h: the Quadrupel board's core in C99, the twin of fcb_sim's Python board (fcb_sim/board/board.py).
 *
 * No dynamic memory: all state is one qb_board_t the caller owns (a static on the M0). No hardware: every read
 * and write goes through hal.h. The parts, each mirroring its Python module:
 *   - the loop (qb_board.c, fcb_sim/board/board.py, scheduler.py): timers on the 32768 Hz RTC set flags; one pass of
 *     qb_poll() runs the flagged tasks in the report's round-robin order (parse, baro, telemetry, heartbeat,
 *     sensor, control); the sensor at 200 Hz (DMP path) or 400 Hz (RAW path), barometer and battery at 20 Hz,
 *     telemetry at link.telemetry_hz, heartbeat and the safety monitor at 10 Hz;
 *   - the mode machine with its guards and NAK reasons (qb_modes.c, fcb_sim/board/modes.py);
 *   - calibration sums and means (qb_modes.c, fcb_sim/board/calibration.py);
 *   - the flight core: cascaded P roll/pitch, yaw P, HEIGHT's PID on the height estimate, PANIC's descent,
 *     mixing with the integer square root (qb_flight.c, fcb_sim/board/flight.py, control.py);
 *   - the height estimator, HeightKalman (qb_height.c, fcb_sim/estimation/height.py);
 *   - the RAW path's attitude filter, ikf's fixed-point twin (ikf_q.c, fcb_sim/estimation/ikf_fixed.py; the
 *     board's set-up and dt in qb_flight.c), or the report's complementary filter (qb_est_comp.c, float or Q16.16);
 *   - the report's Figure 10 height estimator, est.height complementary (qb_est_comp.c);
 *   - commands, telemetry, heartbeats, the link-loss failsafe, the parameter table generated from term's
 *     (qb_board.c, qb_params.c, qb_params.h; fcb_sim/board/commands.py, telemetry.py, param_bindings.py).
 *   - the task profile (qb_prof.c, fcb_sim/board/timing.py's Profiler) and the flash log (qb_log.c,
 *     fcb_sim/board/flash_log.py).
 * Not yet: the BLE handover, RAW filters kalman, kalman-cov and qgate (and ikf in float: the C board's is always the
 * fixed-point twin), the report's estimators on the M0 image (flash), the transmit side's answer budget. docs/firmware.md
 * keeps the list of what is still different.
 *
 * Floating point: the flight core uses qb_real, as the Python board does (the differential test compares them);
 * an M0 build may define QB_REAL=float to halve the soft-float cost.
 */
#ifndef QB_BOARD_H
#define QB_BOARD_H

#include <stdint.h>

#include "ikf_q.h"
#include "qb_consts.h"
#include "qb_console.h"
#include "qb_params.h"
#include "qp_protocol.h"

#ifdef QB_FLOAT
#define QM(fn) fn##f /* the float version of a libm function: expf, atan2f, ... */
#else
#define QM(fn) fn
#endif
typedef QB_REAL qb_real; /* qb_params.h: float with QB_FLOAT, else double */

#include "qb_est_comp.h" /* the report's complementary estimators (qb_real) */

#define QB_VERSION_MAJOR 0
#define QB_VERSION_MINOR 2

/* The tasks (enum qb_task), the loop's periods and the flight's constants: qb_consts.h, generated. */
enum qb_timer { QB_TM_SENSOR, QB_TM_BARO, QB_TM_TELEMETRY, QB_TM_HEARTBEAT, QB_TIMERS };

#define QB_EVENTS 16
#define QB_DEAF_SPANS 8

/* --- the mode machine (qb_modes.c) ------------------------------------------------------------------------ */

enum qb_cal_var { QB_CAL_GX, QB_CAL_GY, QB_CAL_GZ, QB_CAL_AX, QB_CAL_AY, QB_CAL_AZ, QB_CAL_DMP_PHI,
                  QB_CAL_DMP_THETA, QB_CAL_PRESSURE, QB_CAL_VARS };

typedef struct {
    uint8_t code;
    int32_t arg;
} qb_event_t;

typedef struct {
    /* config (fcb_sim.board.modes.ModeConfig) */
    qb_real link_timeout_s;
    qb_real link_failsafe_s; /* stage 1's guard time; 0: PANIC at once (the report's) */
    qb_real calibration_s;   /* mode.calibration_ms: averaging time; 0: for as long as the pilot holds it */
    qb_real panic_countdown_s; /* mode.panic_countdown_ms: 0 the descent (ours); else the report's fixed level */
    int32_t panic_level;
    int32_t trim_step, lift_step;
    /* state */
    uint8_t mode, previous, height_base, pending_target;
    uint8_t calibrated, link_timed_out, battery_low_latched, crashed;
    uint8_t link_hold;      /* the failsafe's stage 1: level, the lift it had, until the link is back or stage 2 */
    int32_t hold_lift;
    qb_real hold_since;
    qp_joystick_t js;
    int32_t trim_roll, trim_pitch, trim_yaw, trim_lift;
    int32_t battery;        /* 10 mV; -1 before the first reading */
    int32_t motor_level;    /* mean motor command, from the control task */
    qb_real now, calibration_started, panic_started, panic_landed_at, low_battery_since;
    uint8_t panic_landed_set, low_battery_set;
    int32_t panic_start_level;
    int64_t sums[QB_CAL_VARS];
    uint32_t counts[QB_CAL_VARS];
    qb_event_t events[QB_EVENTS];
    uint8_t n_events;
    /* the board's listener: called after every change (fcb_sim's ModeMachine.listeners) */
    void (*on_change)(void *ctx, uint8_t old_mode, uint8_t new_mode);
    void *ctx;
} qb_modes_t;

void qb_modes_init(qb_modes_t *m, qb_real link_timeout_s, int32_t panic_level);
int32_t qb_modes_lift(const qb_modes_t *m);
void qb_modes_sticks(const qb_modes_t *m, int32_t out[4]);
int32_t qb_modes_adjust_trim(qb_modes_t *m, int axis, int32_t steps); /* axis: 0 lift, 1 roll, 2 pitch, 3 yaw */
uint8_t qb_modes_request(qb_modes_t *m, int32_t target, qb_real now);
int qb_modes_panic(qb_modes_t *m, qb_real now);
void qb_modes_crash(qb_modes_t *m, qb_real now, int32_t speed_mm_s);
void qb_modes_event(qb_modes_t *m, uint8_t code, int32_t arg);
uint8_t qb_modes_ack_crash(qb_modes_t *m);
void qb_modes_tick(qb_modes_t *m, qb_real now);
qb_real qb_modes_panic_scale(qb_modes_t *m, qb_real now);
void qb_modes_panic_ground(qb_modes_t *m, qb_real now);
/* A valid frame from the PC: stage 1 of the failsafe ends (event LINK_REGAINED). */
void qb_modes_link_back(qb_modes_t *m, qb_real now);
void qb_modes_supervise(qb_modes_t *m, qb_real now, qb_real link_silent_s, int32_t battery, int32_t phi_cdeg,
                        int32_t theta_cdeg);
void qb_modes_cal_add(qb_modes_t *m, int var, int32_t v);
int32_t qb_modes_cal_mean(const qb_modes_t *m, int var);
int qb_modes_flying(const qb_modes_t *m);
int qb_modes_motors_enabled(const qb_modes_t *m);
/* Take the oldest queued event (code, arg); 0 when none. */
int qb_modes_take_event(qb_modes_t *m, qb_event_t *ev);
int32_t qb_tilt_cdeg(int32_t phi_cdeg, int32_t theta_cdeg);

/* --- the height estimator (qb_height.c) ------------------------------------------------------------------- */

#define QB_ANCHOR_MAX 64

typedef struct {
    qb_real p_ref, k_pa_per_m;
    qb_real height, vz, bias, spike, az_earth, baro_raw, innovation;
    qb_real p[10];
    qb_real t_pred;
    int jump_sign, rejumps;
    qb_real t_jump;
    uint32_t baro_rejected, level_changes, trend_resets;
    qb_real trend;
    uint8_t on_ground, anchored, motors_off;
    qb_real rest_s;
    qb_real ground_baro[QB_ANCHOR_MAX];
    uint8_t n_ground_baro;
    qb_real ground_baro_s;
    qb_real captured_height;
    qb_real c[4];
    qb_real c00;
    qb_real stand_baro, acc_lp, ground_ref; /* the standing barometer, the low-passed |f| - g, the floor's height */
    uint8_t snapped, stop_n, stop_kind;      /* on the floor at ground_ref; a jolt's run; the last stop (1 down, 2 up) */
    qb_real stop_v, stop_hold, stop_speed;
    uint32_t stops;
    /* the thrust model (docs/height.md "The thrust model"): the flight core's hint (sum of ae²) and the pack's
     * voltage, the hint lagged as the rotors follow (u), the gain c, the fast means the gate compares; on the legs */
    qb_real thrust_hint, supply_sq, u, thrust_c, az_fast, u_fast;
    uint8_t model_on, on_legs, lifting; /* the model is on when THRUST_MODEL (qb_estimator.h) */
} qb_height_t;

void qb_height_init(qb_height_t *h);
void qb_height_reset(qb_height_t *h, qb_real pressure_pa);
qb_real qb_height_capture(qb_height_t *h);
void qb_height_update_imu(qb_height_t *h, qb_real ax, qb_real ay, qb_real az, qb_real qw, qb_real qx, qb_real qy,
                          qb_real qz, qb_real dt);
void qb_height_update_baro(qb_height_t *h, qb_real pressure_pa, qb_real dt);
int qb_height_unsure(const qb_height_t *h);

/* --- the RAW path's attitude filter: ikf_q.c, fcb_sim/estimation/ikf_fixed.py bit for bit ------------------ */

typedef struct {
    ikfq_t q;   /* set up from integers (ikfq_init_q): the M0 links no double arithmetic */
    qb_real dt; /* the dt its five dt constants were derived from (0: none yet) */
} qb_ikf_t;

void qb_ikf_reset(qb_ikf_t *f);
/* Gyro (rad/s) and specific force (m/s^2), chip frame z up, and the time step (s). */
void qb_ikf_update(qb_ikf_t *f, qb_real gx, qb_real gy, qb_real gz, qb_real ax, qb_real ay, qb_real az, qb_real dt);
/* The attitude predicted over the latency (w x y z), and its ZYX angles (roll, pitch, yaw; rad, z up). */
void qb_ikf_quaternion(const qb_ikf_t *f, qb_real q[4]);
void qb_ikf_angles(const qb_ikf_t *f, qb_real out[3]);

/* --- the heading at rest (qb_flight.c, fcb_sim/estimation/heading.py's HeadingHold) ------------------------ */

typedef struct {
    qb_real rate, offset, prev;    /* the drift rate learnt while still (rad/s), the drift since reset (rad) */
    uint8_t have_prev;
    uint32_t n;                    /* the still stretch's least-squares sums */
    qb_real t, y, st, sy, sty, stt;
} qb_heading_t;

/* --- the flight core (qb_flight.c) ------------------------------------------------------------------------ */

typedef struct {
    qb_real yaw_p, p1, p2, height_p, height_d, height_i;
} qb_gains_t;

typedef struct {
    qb_gains_t g;
    qb_height_t hest;
    qb_ikf_t ikf;     /* the RAW path's filter: runs on every IMU sample, so it is converged on entering RAW */
    uint8_t attitude; /* est.attitude: QB_ATTITUDE_IKF, or QB_ATTITUDE_COMPLEMENTARY (comp) */
    uint8_t height_comp; /* est.height complementary: hcomp (Figure 10) instead of hest */
#if QB_REPORT_EST
    qb_comp_t comp;
    qb_hcomp_t hcomp;
#endif
    uint32_t n_imu;
    uint8_t mode, calibrated, have_dmp, height_raw, sp_from_est, panic_landed;
    qb_real g_off[3], a_off[3];
    qb_real cal_dmp_phi, cal_dmp_theta, cal_pressure;
    qb_real sp, sq, sr, sax, say, saz;
    qb_real dmp_phi, dmp_theta, dmp_psi;
    qb_real phi, theta;
    uint8_t psi_raw;
    qb_real q[4];
    qb_real height, vz, setpoint;
    qb_real z_base, z_int, sp_cap0, sp_base, sp_offset;
    int32_t lift_entry;
    qb_real panic_scale, panic_i, panic_level, panic_start, land_s;
    uint8_t panic_hold; /* the report's PANIC (mode.panic_countdown_ms > 0): a fixed level, no descent loop */
    int32_t panic_ae;
    uint16_t ae[4];
    uint32_t stops_seen;           /* the height estimator's hard stops already reported */
    uint8_t wall_n, walls;         /* a sideways jolt's run; wall contacts not yet reported */
    qb_real wall_quiet;            /* s until a new wall contact may be reported */
    qb_heading_t heading_dmp, heading_raw; /* the headings without a compass, their drift learnt while still */
    qb_real hpsi_dmp, hpsi_raw;    /* corrected (rad, FRD) */
    qb_real still_s, head_dt;
    uint8_t still, n_head;
    int32_t drift_reported;        /* cdeg */
} qb_flight_t;

void qb_flight_init(qb_flight_t *fc);
/* est.attitude (QB_ATTITUDE_*), est.fixed_point and est.k_gyro: the RAW filter afresh. est.height complementary or
 * not: that estimator afresh at the calibration's pressure. Reset the height estimators at a pressure. */
void qb_flight_set_filter(qb_flight_t *fc, int filter, int fixed, qb_real k_gyro);
void qb_flight_set_height(qb_flight_t *fc, int complementary);
void qb_flight_reset_height(qb_flight_t *fc, qb_real pressure);
void qb_flight_set_calibration(qb_flight_t *fc, const qb_real gyro[3], const qb_real accel[3], qb_real dmp_phi,
                               qb_real dmp_theta, qb_real pressure);
void qb_flight_imu(qb_flight_t *fc, const int16_t raw[6], qb_real dt);
void qb_flight_dmp(qb_flight_t *fc, const float q[4]);
void qb_flight_baro(qb_flight_t *fc, qb_real pressure_pa, qb_real dt);
void qb_flight_enter_mode(qb_flight_t *fc, uint8_t mode, int32_t lift);
/* HEIGHT: the set point moved by dm metres (the lift keys), kept in lo..hi, never against the press; the new one. */
qb_real qb_flight_move_setpoint(qb_flight_t *fc, qb_real dm, qb_real lo, qb_real hi);
void qb_flight_control(qb_flight_t *fc, uint8_t mode, const int32_t sticks[4], qb_real dt, uint16_t out[4]);
void qb_flight_attitude_cdeg(const qb_flight_t *fc, int32_t out[3]);
/* A hard stop felt since the last call (EventCode.CONTACT's arg: kind << 16 | mm/s), or -1. */
int32_t qb_flight_pending_contact(qb_flight_t *fc);
/* The heading drift to report (EventCode.HEADING_DRIFT, 0.01 deg) into *cdeg: 1, or 0 for none now. */
int qb_flight_pending_heading_drift(qb_flight_t *fc, int32_t *cdeg);
void qb_quaternion_to_euler(qb_real w, qb_real x, qb_real y, qb_real z, qb_real out[3]);
uint32_t qb_isqrt(uint32_t square);
void qb_mix(int32_t z, qb_real l, qb_real m, qb_real n, int armed, uint16_t out[4]);

/* --- the task profile (qb_prof.c) -------------------------------------------------------------------------- */

#define QB_PROF_BUCKETS 64u

typedef struct {
    uint32_t n, pn;           /* runs, periods */
    uint64_t sum_us, psum_us; /* their sums */
    uint64_t last_start;
    uint8_t started;
    uint16_t misses;          /* control periods of at least WCET99 */
    uint16_t hist[QB_PROF_BUCKETS]; /* durations, 4 buckets per octave */
} qb_task_stats_t;

typedef struct {
    qb_task_stats_t t[QB_TASKS];
    uint64_t busy_us, mark_t, mark_busy;
    uint8_t cpu_load;
} qb_prof_t;

void qb_prof_reset(qb_prof_t *p, uint64_t now);
/* A task ran from ``start`` for ``dur`` µs (hal_time_us before and after); returns its period, 0 the first time. */
uint32_t qb_prof_ran(qb_prof_t *p, int task, uint64_t start, uint32_t dur);
/* Count a control period against the deadline (WCET99 of the path); 1 if it missed. */
int qb_prof_control_period(qb_prof_t *p, int raw_path, uint32_t period);
/* The CPU load (%) since the previous call (the Status packet's). */
uint8_t qb_prof_load(qb_prof_t *p, uint64_t now);
void qb_prof_packet(const qb_prof_t *p, int task, qp_profile_t *out);

/* --- the flash log (qb_log.c) -------------------------------------------------------------------------------- */

#define QB_LOG_VARS 18          /* fcb_sim/board/flash_log.py LOG_VARS */
#define QB_LOG_BYTES (128u * 1024u)
#define QB_LOG_CHUNK 12u        /* a LogChunk's bytes */
#define QB_LOG_RECORD_MAX 212u  /* the most one record (and a flush) adds */
#define QB_DOWNLOAD_PERIOD_US 20000u
#define QB_DOWNLOAD_CHUNKS_PER_RUN 8u /* 400 chunks a second: what 115200 baud carries beside the heartbeats */

typedef struct {
    int32_t prev1, prev2; /* the last two reconstructed (quantised) values */
    int64_t e1, e2, a;    /* the predictors' decayed errors, LOCO-I's sum of residuals */
    int32_t n;
} qb_rice_t;

typedef struct {
    uint8_t scheme, state;              /* QB_SCHEME_*, QP_LOG_STATE_* */
    uint32_t size, used, records;
    uint32_t seg_start, seg_records, data_start, count;
    uint64_t acc;                       /* the bit writer's partial byte */
    uint8_t nbits;
    int64_t recon[QB_LOG_VARS];         /* delta8's reconstruction */
    qb_rice_t rice[QB_LOG_VARS];
    uint32_t flash_errors;              /* writes the HAL refused */
    uint8_t full_reported;              /* LOG_FULL said for this recording */
    uint8_t dl_active;                  /* a download runs: chunks instead of telemetry */
    uint32_t dl_next, dl_sent;
} qb_log_t;

void qb_log_init(qb_log_t *l, uint32_t size, uint8_t scheme);
uint8_t qb_log_start(qb_log_t *l);
/* One record (the board's LOG_VARS, in board units) if recording; returns the bytes programmed. */
uint32_t qb_log_append(qb_log_t *l, const int64_t values[QB_LOG_VARS]);
uint8_t qb_log_stop(qb_log_t *l);
uint8_t qb_log_reset(qb_log_t *l, int in_safe);
uint32_t qb_log_chunks(const qb_log_t *l);
void qb_log_chunk(const qb_log_t *l, uint32_t index, uint8_t out[QB_LOG_CHUNK]);
uint32_t qb_log_crc32(const qb_log_t *l);
/* The board's side (qb_log.c, after the board's declarations below). */
struct qb_board;
void qb_log_task(struct qb_board *b);                          /* the logging task: one record */
void qb_log_send_status(struct qb_board *b, uint8_t state);    /* a LogStatus packet */
void qb_log_begin_download(struct qb_board *b, uint32_t first); /* after LOG_DOWNLOAD's Ack */
void qb_log_download_step(struct qb_board *b);                 /* one telemetry run's chunks */
void qb_log_end_download(struct qb_board *b);                  /* LogStatus, LOG_DONE */

/* --- the board (qb_board.c) ------------------------------------------------------------------------------- */

typedef struct {
    uint16_t board_id;
    qb_real link_timeout_s;
    qb_real link_failsafe_s;
    uint32_t phase_tk[QB_TIMERS]; /* the timers' first expiry, RTC ticks (fcb_sim's scheduler draws them) */
    uint8_t boot_hello;
} qb_config_t;

typedef struct qb_board {
    qb_config_t cfg;
    qb_modes_t modes;
    qb_flight_t core;
    qp_encoder_t enc;
    qp_decoder_t dec;
    uint64_t now;
    uint8_t flags[QB_TASKS];
    uint64_t next_tk[QB_TIMERS];
    uint64_t next_us[QB_TIMERS];
    uint8_t rr;
    uint8_t raw_path;               /* the sensor path: 1 RAW (400 Hz), 0 DMP (200 Hz) */
    uint8_t sample_set, baro_set, sticks_set, last_frame_set, hb_sent_set, hb_rtt_fresh, have_last;
    uint64_t sample_t, baro_t, last_frame_us, hb_sent_us, last_cmd_us;
    uint16_t hb_sent_counter;
    uint32_t rtt_us;
    uint32_t heartbeats, telemetry_runs;
    uint64_t height_due, status_due;
    int32_t sticks_used[4];
    uint16_t ae[4];
    int32_t pressure, temperature;
    uint16_t battery;
    qp_command_t last_cmd;
    qp_ack_t last_ack;
    /* parameters the core does not hold itself */
    int32_t telemetry_hz, sensor_path, scheduler, stick_reaction, queue_rule, log_scheme, attitude_filter;
    int32_t k_gyro_raw, fixed_point, height_estimator, heartbeat_ms;
    uint32_t tx_dropped;
    /* the link timer's deaf spans: board time a starved simulator could not run (not the PC's silence) */
    uint64_t deaf[QB_DEAF_SPANS][2];
    uint8_t n_deaf;
    uint64_t lag_max_us, lag_report_at;
    uint32_t overflow_reported;  /* receive-queue drops already said (event OVERFLOW) */
    uint64_t overflow_report_at;
    qb_prof_t prof;              /* the task profile (PROFILE, the Status packet's CPU load) */
    qb_log_t log;                /* the flash log (LOG_*) */
    uint64_t misses_reported_at;
    uint8_t misses_reported;
    /* qb_console.c: the bench motor test and qb_log's counts */
    qb_motortest_t mt;
    uint32_t log_sent, log_dropped;
} qb_board_t;

/* A packet to the PC, and an Event now (the tasks in qb_board.c, qb_log.c). */
void qb_send(qb_board_t *b, const qp_packet_t *pkt);
void qb_send_event(qb_board_t *b, uint8_t code, int32_t arg);
void qb_config_default(qb_config_t *cfg);
void qb_init(qb_board_t *b, const qb_config_t *cfg);
/* Run every task due at hal_time_us() (the timers that expired, bytes that arrived). */
void qb_poll(qb_board_t *b);
/* The board time at which a timer next expires (a driver sleeps until then, or until bytes arrive). */
uint64_t qb_next_event_us(const qb_board_t *b);
/* A simulator's driver could not run the board from now until ``until_us`` (its process got no CPU): that time is
 * not the PC's silence (``slip``: the board's clock skips it instead), and a lag of 100 ms or more is said as event
 * SIM_LAG, at most once a second (fcb_sim/board/linktimer.py). A real board never calls it. */
void qb_starved(qb_board_t *b, uint64_t until_us, int slip);
/* Board time since the last valid frame, less the time the board could not listen; 0 before the first. */
uint64_t qb_link_silent_us(qb_board_t *b);
/* The receive queue's rule (link.queue_rule), for the UART's receive interrupt: 1 when ``frames`` frames waiting
 * in the queue (its 0x00 delimiters) mean the whole queue goes (discard-20: the report's parser, section 3.4),
 * 0 to keep it (bounded: only what does not fit is dropped). fcb_sim/board/uart.py's Uart.receive. */
int qb_rx_discard(const qb_board_t *b, uint32_t frames);
/* Feed received bytes to the parser at once (the host backend's UART interrupt; qb_poll reads the HAL too). */
void qb_receive(qb_board_t *b, const uint8_t *data, size_t len);

/* Parameters (qb_params.c): the raw value in force, and a change with the guards of fcb_sim/board/param_bindings.py. */
int32_t qb_param_get(const qb_board_t *b, int id);
uint8_t qb_param_set(qb_board_t *b, int id, int32_t raw, int mode_guard);
/* The index in QB_RULES of the first rule `id` = `raw` would break with the values in force, or -1. */
int qb_param_broken_rule(const qb_board_t *b, int id, int32_t raw);
const qb_param_spec_t *qb_param_spec(int id);
/* The raw number for value ``v`` kept inside the table's range: round(v / scale) (half to even, Python's round)
 * clipped to lo..hi; a value past either end (a burst of key presses) is that end. */
int32_t qb_param_raw_clamped(const qb_param_spec_t *s, qb_real v);

#endif /* QB_BOARD_H */
