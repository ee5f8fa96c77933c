/* The task bodies for the Cortex-M0 emulator (fcb_sim/m0emu.py, bench.profile): the filter step and the control
 * step on buffers the emulator fills, with entry points it calls one at a time. Timing counts the tm_*_step
 * calls only; tm_filter_init and tm_filter_export run outside it. Not the board's main: there is none here. */
#include "ctl_q.h"
#include "ikf_q.h"

void tm_filter_init(double dt);
void tm_filter_step(void);
void tm_filter_export(void);
void tm_control_step(void);
void tasks_main(void);

ikfq_t tm_filter;
int32_t tm_g[3], tm_a[3], tm_q[4], tm_angles[2];
int64_t tm_state[29];
ctlq_gains_t tm_gains;
ctlq_in_t tm_in;
int16_t tm_ae[4];

void tm_filter_init(double dt)
{
    ikfq_formats_t f;
    ikfq_params_t p;
    ikfq_default_formats(&f);
    ikfq_default_params(&p);
    ikfq_init(&tm_filter, &f, &p);
    ikfq_set_dt(&tm_filter, dt);
}

/* The filter task: a sample in, the attitude and the angles the control law reads out. */
void tm_filter_step(void)
{
    ikfq_step(&tm_filter, tm_g, tm_a);
    ikfq_predicted(&tm_filter, tm_q);
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
    tm_filter_init(0.0025);
    for (;;) {
        tm_filter_step();
        tm_filter_export();
        tm_control_step();
    }
}
