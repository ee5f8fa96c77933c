/* qb_prof.c: the task profile, fcb_sim/board/timing.py's Profiler in C. The loop (qb_board.c) reads hal_time_us()
 * before and after every task: its duration and period (start to start) go into per-task figures, the busy time
 * into the CPU load the Status packet carries, and a control period of at least WCET99 is a deadline miss.
 *
 * RAM, not a list: the Python board sorts its last 50 000 durations for the percentiles; the board keeps a
 * histogram per task, 4 buckets per octave (each bucket's upper end is reported: at most 19 % above the true
 * percentile, never below it), halved when a bucket would overflow (the shape is kept, the oldest weigh less). */
#include <string.h>

#include "qb_board.h"

/* fcb_sim/board/timing.py WCET99_US: a control period this long is a deadline miss (Figure 14's WCET99 at 400 Hz,
 * scaled to the DMP path's 200 Hz); tests/firmware/test_cboard_profile.py checks they are still those. */
#define WCET99_RAW_US 2987u
#define WCET99_DMP_US 5974u

static unsigned bucket_of(uint32_t d)
{
    unsigned msb = 2;
    if (d < 4u)
        return d;
    while (msb < 31u && (d >> (msb + 1u)) != 0u)
        msb++;
    if (msb > 16u)
        return QB_PROF_BUCKETS - 1u;
    return 4u * (msb - 1u) + ((d >> (msb - 2u)) & 3u);
}

static uint32_t bucket_top(unsigned b)
{
    unsigned msb, mant;
    if (b < 4u)
        return b;
    msb = b / 4u + 1u;
    mant = b % 4u;
    return ((4u + mant) << (msb - 2u)) + (1u << (msb - 2u)) - 1u;
}

void qb_prof_reset(qb_prof_t *p, uint64_t now)
{
    uint64_t busy = p->busy_us, mark_t = p->mark_t, mark_busy = p->mark_busy;
    uint8_t load = p->cpu_load;
    memset(p, 0, sizeof *p);
    p->busy_us = busy; /* the CPU load runs on across a reset, as the Python board's */
    p->mark_t = mark_t;
    p->mark_busy = mark_busy;
    p->cpu_load = load;
    (void)now;
}

uint32_t qb_prof_ran(qb_prof_t *p, int task, uint64_t start, uint32_t dur)
{
    qb_task_stats_t *s = &p->t[task];
    unsigned b = bucket_of(dur), i;
    uint32_t period = 0;
    p->busy_us += dur;
    s->n++;
    s->sum_us += dur;
    if (s->hist[b] == 0xFFFFu) {
        for (i = 0; i < QB_PROF_BUCKETS; i++)
            s->hist[i] = (uint16_t)(s->hist[i] / 2u);
    }
    s->hist[b]++;
    if (s->started) {
        /* a clock that steps back (the host's: each pass starts again at the lockstep time) is a period of 0 */
        uint64_t d = start > s->last_start ? start - s->last_start : 0u;
        period = d > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)d;
        s->pn++;
        s->psum_us += period;
    }
    s->last_start = start > s->last_start ? start : s->last_start;
    s->started = 1;
    return period;
}

int qb_prof_control_period(qb_prof_t *p, int raw_path, uint32_t period)
{
    qb_task_stats_t *s = &p->t[QB_T_CONTROL];
    if (period < (raw_path ? WCET99_RAW_US : WCET99_DMP_US))
        return 0;
    if (s->misses < 0xFFFFu)
        s->misses++;
    return 1;
}

uint8_t qb_prof_load(qb_prof_t *p, uint64_t now)
{
    if (now > p->mark_t) {
        uint64_t dt = now - p->mark_t, busy = p->busy_us - p->mark_busy;
        uint64_t pct = (200u * busy + dt) / (2u * dt);
        p->cpu_load = (uint8_t)(pct > 100u ? 100u : pct);
    }
    p->mark_t = now;
    p->mark_busy = p->busy_us;
    return p->cpu_load;
}

/* The duration at rank floor(q_num / q_den * n) of the histogram (Python: sorted(d)[int(q * n)]). */
static uint32_t percentile(const qb_task_stats_t *s, uint32_t q_num, uint32_t q_den)
{
    uint32_t n = 0, rank, cum = 0;
    unsigned i;
    for (i = 0; i < QB_PROF_BUCKETS; i++)
        n += s->hist[i];
    if (n == 0)
        return 0;
    rank = (uint32_t)((uint64_t)n * q_num / q_den);
    for (i = 0; i < QB_PROF_BUCKETS; i++) {
        cum += s->hist[i];
        if (cum > rank)
            return bucket_top(i);
    }
    return bucket_top(QB_PROF_BUCKETS - 1u);
}

static uint16_t u16(uint64_t v)
{
    return (uint16_t)(v > 0xFFFFu ? 0xFFFFu : v);
}

void qb_prof_packet(const qb_prof_t *p, int task, qp_profile_t *out)
{
    const qb_task_stats_t *s = &p->t[task];
    out->task = (uint8_t)task;
    out->mean_us = u16(s->n ? (s->sum_us + s->n / 2u) / s->n : 0u);
    out->p99_us = u16(percentile(s, 99u, 100u));
    out->p999_us = u16(percentile(s, 999u, 1000u));
    out->period_us = (uint32_t)(s->pn ? (s->psum_us + s->pn / 2u) / s->pn : 0u);
    out->misses = s->misses;
}
