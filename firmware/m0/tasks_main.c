/* The task bodies for the Cortex-M0 emulator (fcb_sim/hosts/m0emu.py, bench.profile): the filter step and the control
 * step on buffers the emulator fills, with entry points it calls one at a time. Timing counts the tm_*_step
 * calls only; tm_filter_init and tm_filter_export run outside it. Not the board's main: there is none here. */
#include "ctl_q.h"
#include "ikf_q.h"

void tm_filter_init(void);
void tm_filter_step(void);
void tm_filter_export(void);
void tm_control_step(void);
void tasks_main(void);

ikfq_t tm_filter;
ikfq_formats_t tm_formats;
ikfq_consts_t tm_consts;
int32_t tm_g[3], tm_a[3], tm_q[4], tm_angles[2];
int64_t tm_state[IKFQ_STATE_N];
ctlq_gains_t tm_gains;
ctlq_in_t tm_in;
int16_t tm_ae[4];

/* From the constants the emulator wrote (a board would hold them in a table): no double arithmetic linked. */
void tm_filter_init(void)
{
    ikfq_init_q(&tm_filter, &tm_formats, &tm_consts);
}

/* The filter task: a sample in, the attitude and the angles the control law reads out. */
void tm_filter_step(void)
{
    ikfq_step(&tm_filter, tm_g, tm_a);
    ikfq_predicted(&tm_filter, tm_q);
    if (tm_filter.lite) /* the variant that fits reads its angles cheaply too */
        ctlq_angles_lite(tm_q, &tm_angles[0], &tm_angles[1]);
    else
        ctlq_angles(tm_q, &tm_angles[0], &tm_angles[1]);
}

void tm_filter_export(void)
{
    ikfq_state(&tm_filter, tm_state);
}

void tm_control_step(void)
{
    ctlq_law(&tm_gains, &tm_in, tm_angles[0], tm_angles[1], tm_ae);
}

/* The ELF's entry: it reaches every entry point, so --gc-sections keeps them (the emulator never runs it). */
void tasks_main(void)
{
    tm_filter_init();
    for (;;) {
        tm_filter_step();
        tm_filter_export();
        tm_control_step();
    }
}
