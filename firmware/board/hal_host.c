/* hal_host.c: the host backend of hal.h. The board runs in LOCKSTEP with a simulator that owns the clock:
 * fcb_sim/hosts/cboard.py loads this as a shared library (ctypes) and calls qbh_advance(until_us), which runs every
 * task due before that board time, each at the instant its timer expires. The sensors and motors are callbacks
 * into the simulator (given the board time, so the physics advances to it first); the UART is two byte queues
 * the simulator fills and drains. Nothing here reads a wall clock: the same inputs give the same flight.
 *
 * The task profile (qb_prof.c) times each task by hal_time_us() before and after it. In lockstep the board time
 * does not move while a task runs, so within one pass of the loop hal_time_us() adds the thread's CPU time spent
 * in the board's own code since the pass began (the simulator's callbacks for the sensors and motors are taken
 * out): the host's real cost of each task, while the pass's first reading, the board's now, is the lockstep time
 * exactly (the flight stays the same for the same inputs; only the profile's figures come from the host's CPU).
 *
 * Several boards can live in one process: each is a qbh_t (qbh_size() bytes, owned by the caller), and the HAL
 * functions act on the one being run.
 */
#define _POSIX_C_SOURCE 199309L /* clock_gettime */
#include <string.h>
#include <time.h>

#include "hal.h"
#include "qb_board.h"

#define RX_BYTES 4096u
#define TX_BYTES 65536u
#define FLASH_BYTES QB_LOG_BYTES

typedef void (*qbh_imu_fn)(uint64_t t_us, int16_t *out);
typedef int (*qbh_dmp_fn)(uint64_t t_us, float *q);
typedef void (*qbh_baro_fn)(uint64_t t_us, int32_t *out);
typedef int (*qbh_battery_fn)(uint64_t t_us);
typedef void (*qbh_motors_fn)(uint64_t t_us, const uint16_t *ae);
typedef int32_t (*qbh_impact_fn)(uint64_t t_us);

typedef struct qbh {
    qb_board_t board;
    uint64_t time_us;
    qbh_imu_fn imu;
    qbh_dmp_fn dmp;
    qbh_baro_fn baro;
    qbh_battery_fn battery;
    qbh_motors_fn motors;
    qbh_impact_fn impact;
    uint8_t rx[RX_BYTES];
    size_t rx_len;
    uint32_t rx_dropped;
    uint32_t rx_discarded; /* bytes the queue rule threw away (discard-20) */
    uint8_t tx[TX_BYTES];
    size_t tx_len;
    uint8_t flash[FLASH_BYTES]; /* the flash log's NOR flash: erased 0xFF, programming ANDs */
    uint8_t pass;              /* inside a pass of the loop: hal_time_us() counts the board's CPU time */
    uint64_t cpu_base_ns;      /* the thread's CPU time when the pass began */
    uint64_t callback_ns;      /* CPU time spent in the simulator's callbacks since then */
} qbh_t;

/* Exported for ctypes (fcb_sim/hosts/cboard.py); declared here, not in a header: nothing else calls them. */
size_t qbh_size(void);
void qbh_set_callbacks(qbh_t *h, qbh_imu_fn imu, qbh_dmp_fn dmp, qbh_baro_fn baro, qbh_battery_fn battery,
                       qbh_motors_fn motors, qbh_impact_fn impact);
void qbh_init(qbh_t *h, uint16_t board_id, double link_timeout_s, const uint32_t phases[4], int boot_hello,
              uint64_t now_us);
void qbh_advance(qbh_t *h, uint64_t until_us);
void qbh_receive(qbh_t *h, const uint8_t *data, size_t len);
size_t qbh_transmit(qbh_t *h, uint8_t *out, size_t cap);
uint64_t qbh_now(const qbh_t *h);
uint64_t qbh_next_event_us(const qbh_t *h);
int qbh_mode(const qbh_t *h);
void qbh_motors(const qbh_t *h, uint16_t out[4]);
void qbh_state(const qbh_t *h, double out[16]);
uint32_t qbh_rx_dropped(const qbh_t *h);
uint32_t qbh_rx_discarded(const qbh_t *h);
size_t qbh_log_encode(qbh_t *h, int scheme, const int64_t *rows, size_t n, uint8_t *out, size_t cap);
int32_t qbh_param(const qbh_t *h, int id);
int qbh_set_param(qbh_t *h, int id, int32_t raw);
void qbh_starved(qbh_t *h, uint64_t until_us, int slip);

static qbh_t *cur; /* the board being run: the HAL functions below act on it */

static uint64_t cpu_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

/* A new pass of the loop: its first hal_time_us() is the lockstep time (module comment). */
static void begin_pass(qbh_t *h)
{
    cur = h;
    h->pass = 0;
}

/* The simulator's callbacks do not count as the board's time. */
static uint64_t callback_begin(void)
{
    return cur->pass ? cpu_ns() : 0u;
}

static void callback_end(uint64_t t0)
{
    if (cur->pass)
        cur->callback_ns += cpu_ns() - t0;
}

uint64_t hal_time_us(void)
{
    uint64_t spent;
    if (!cur->pass) {
        cur->pass = 1;
        cur->cpu_base_ns = cpu_ns();
        cur->callback_ns = 0;
        return cur->time_us;
    }
    spent = cpu_ns() - cur->cpu_base_ns;
    spent = spent > cur->callback_ns ? spent - cur->callback_ns : 0u;
    return cur->time_us + spent / 1000u;
}

size_t hal_uart_read(uint8_t *buf, size_t cap)
{
    size_t n = cur->rx_len < cap ? cur->rx_len : cap;
    memcpy(buf, cur->rx, n);
    memmove(cur->rx, cur->rx + n, cur->rx_len - n);
    cur->rx_len -= n;
    return n;
}

size_t hal_uart_write(const uint8_t *data, size_t len)
{
    if (TX_BYTES - cur->tx_len < len)
        return 0; /* nobody drained the queue: the frame is dropped whole, never cut */
    memcpy(cur->tx + cur->tx_len, data, len);
    cur->tx_len += len;
    return len;
}

uint32_t hal_uart_dropped(void)
{
    return cur->rx_dropped;
}

void hal_imu_read(int16_t out[6])
{
    uint64_t t0 = callback_begin();
    cur->imu(cur->time_us, out);
    callback_end(t0);
}

int hal_dmp_read(float q[4])
{
    uint64_t t0 = callback_begin();
    int got = cur->dmp(cur->time_us, q);
    callback_end(t0);
    return got;
}

void hal_baro_read(int32_t *pressure_pa, int32_t *temperature_cdeg)
{
    int32_t v[2];
    uint64_t t0 = callback_begin();
    cur->baro(cur->time_us, v);
    callback_end(t0);
    *pressure_pa = v[0];
    *temperature_cdeg = v[1];
}

uint16_t hal_battery_read(void)
{
    uint64_t t0 = callback_begin();
    uint16_t v = (uint16_t)cur->battery(cur->time_us);
    callback_end(t0);
    return v;
}

void hal_motors_set(const uint16_t ae[4])
{
    uint64_t t0 = callback_begin();
    cur->motors(cur->time_us, ae);
    callback_end(t0);
}

int32_t hal_impact_mm_s(void)
{
    uint64_t t0 = callback_begin();
    int32_t v = cur->impact(cur->time_us);
    callback_end(t0);
    return v;
}

int hal_flash_write(uint32_t addr, const uint8_t *data, size_t len)
{
    size_t i;
    if (addr > FLASH_BYTES || len > FLASH_BYTES - addr)
        return -1;
    for (i = 0; i < len; i++)
        cur->flash[addr + i] &= data[i];
    return 0;
}

int hal_flash_read(uint32_t addr, uint8_t *data, size_t len)
{
    if (addr > FLASH_BYTES || len > FLASH_BYTES - addr)
        return -1;
    memcpy(data, cur->flash + addr, len);
    return 0;
}

int hal_flash_erase(uint32_t addr, size_t len)
{
    if (addr > FLASH_BYTES || len > FLASH_BYTES - addr)
        return -1;
    memset(cur->flash + addr, 0xFF, len);
    return 0;
}

/* --- the simulator's side --------------------------------------------------------------------------------- */

size_t qbh_size(void)
{
    return sizeof(qbh_t);
}

void qbh_set_callbacks(qbh_t *h, qbh_imu_fn imu, qbh_dmp_fn dmp, qbh_baro_fn baro, qbh_battery_fn battery,
                       qbh_motors_fn motors, qbh_impact_fn impact)
{
    h->imu = imu;
    h->dmp = dmp;
    h->baro = baro;
    h->battery = battery;
    h->motors = motors;
    h->impact = impact;
}

void qbh_init(qbh_t *h, uint16_t board_id, double link_timeout_s, const uint32_t phases[4], int boot_hello,
              uint64_t now_us)
{
    qb_config_t cfg;
    int i;
    qb_config_default(&cfg);
    cfg.board_id = board_id;
    cfg.link_timeout_s = link_timeout_s;
    cfg.boot_hello = (uint8_t)boot_hello;
    for (i = 0; i < QB_TIMERS; i++)
        cfg.phase_tk[i] = phases[i];
    h->time_us = now_us;
    h->rx_len = h->tx_len = 0;
    h->rx_dropped = h->rx_discarded = 0;
    memset(h->flash, 0xFF, sizeof h->flash);
    begin_pass(h);
    qb_init(&h->board, &cfg);
}

void qbh_advance(qbh_t *h, uint64_t until_us)
{
    cur = h;
    for (;;) {
        uint64_t t = qb_next_event_us(&h->board);
        if (t >= until_us)
            break;
        if (t > h->time_us)
            h->time_us = t;
        begin_pass(h);
        qb_poll(&h->board);
    }
    if (until_us > h->time_us)
        h->time_us = until_us;
}

void qbh_receive(qbh_t *h, const uint8_t *data, size_t len)
{
    size_t room = RX_BYTES - h->rx_len, n = len < room ? len : room, i;
    uint32_t frames = 0;
    cur = h;
    memcpy(h->rx + h->rx_len, data, n);
    h->rx_len += n;
    h->rx_dropped += (uint32_t)(len - n);
    for (i = 0; i < h->rx_len; i++)
        frames += h->rx[i] == 0;
    if (n && qb_rx_discard(&h->board, frames)) { /* the board's queue rule: the whole queue goes */
        h->rx_discarded += (uint32_t)h->rx_len;
        h->rx_len = 0;
    }
    begin_pass(h);
    qb_poll(&h->board); /* the UART interrupt flags the parser: it runs now */
}

size_t qbh_transmit(qbh_t *h, uint8_t *out, size_t cap)
{
    size_t n = h->tx_len < cap ? h->tx_len : cap;
    memcpy(out, h->tx, n);
    memmove(h->tx, h->tx + n, h->tx_len - n);
    h->tx_len -= n;
    return n;
}

uint64_t qbh_now(const qbh_t *h)
{
    return h->time_us;
}

uint64_t qbh_next_event_us(const qbh_t *h)
{
    return qb_next_event_us(&h->board);
}

int qbh_mode(const qbh_t *h)
{
    return h->board.modes.mode;
}

void qbh_motors(const qbh_t *h, uint16_t out[4])
{
    memcpy(out, h->board.ae, sizeof h->board.ae);
}

/* The figures a test or a bench reads: phi theta psi (rad), height vz setpoint (m, m/s), sp sq sr, calibrated,
 * link timed out, crashed, trim lift, motor level, battery, pressure. */
void qbh_state(const qbh_t *h, double out[16])
{
    const qb_board_t *b = &h->board;
    out[0] = b->core.phi;
    out[1] = b->core.theta;
    out[2] = b->core.dmp_psi;
    out[3] = b->core.height;
    out[4] = b->core.vz;
    out[5] = b->core.setpoint;
    out[6] = b->core.sp;
    out[7] = b->core.sq;
    out[8] = b->core.sr;
    out[9] = b->modes.calibrated;
    out[10] = b->modes.link_timed_out;
    out[11] = b->modes.crashed;
    out[12] = b->modes.trim_lift;
    out[13] = b->modes.motor_level;
    out[14] = b->battery;
    out[15] = b->pressure;
}

uint32_t qbh_rx_dropped(const qbh_t *h)
{
    return h->rx_dropped;
}

/* The flash log's encoder alone, for the tests (fcb_sim.board.flash_log.encode_log's twin): ``n`` records of
 * QB_LOG_VARS values into one segment of an erased flash; returns the used bytes (copied to ``out`` up to
 * ``cap``). It uses, and erases, this board's flash: a board that logs must not be asked. */
size_t qbh_log_encode(qbh_t *h, int scheme, const int64_t *rows, size_t n, uint8_t *out, size_t cap)
{
    qb_log_t l;
    size_t i;
    cur = h;
    memset(h->flash, 0xFF, sizeof h->flash);
    qb_log_init(&l, QB_LOG_BYTES, (uint8_t)scheme);
    qb_log_start(&l);
    for (i = 0; i < n; i++)
        qb_log_append(&l, rows + i * QB_LOG_VARS);
    qb_log_stop(&l);
    memcpy(out, h->flash, l.used < cap ? l.used : cap);
    return l.used;
}

uint32_t qbh_rx_discarded(const qbh_t *h)
{
    return h->rx_discarded;
}

int32_t qbh_param(const qbh_t *h, int id)
{
    return qb_param_get(&h->board, id);
}

/* A parameter set at boot, as a preset or file would (SAFE: every guard but the mode's); returns the Nak. */
int qbh_set_param(qbh_t *h, int id, int32_t raw)
{
    cur = h;
    return qb_param_set(&h->board, id, raw, 0);
}

/* The driver could not run the board until ``until_us`` (fcb_sim/hosts/serve.py's starved wake-up). */
void qbh_starved(qbh_t *h, uint64_t until_us, int slip)
{
    cur = h;
    qb_starved(&h->board, until_us, slip);
}
