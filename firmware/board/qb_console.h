/* qb_console.h: the board's own debug lines (qb_log) and the bench motor test (Op.MOTOR_TEST).
 *
 * qb_log(b, level, fmt, ...) formats a line (a small printf: %d %i %u %x %c %s %%, with an ignored 'l') of at
 * most QB_LOG_MAX bytes and sends it to the terminal as Text packets (13 bytes each; QP_TEXT_MORE on all but the
 * last), so a team prints without breaking the link: the terminal shows the lines on its console (Ctrl+T). A line
 * that does not fit the UART's queue whole is dropped and counted (b->log_dropped), never sent in part.
 * The Python twin: fcb_sim/board/console.py.
 *
 * The motor test (docs/modes.md, "The motor test"; the Python twin fcb_sim/board/motortest.py): the command's
 * guards (SAFE only, lift at zero, no unacknowledged crash, level <= QP_MOTOR_TEST_MAX_LEVEL, a mask of the four
 * motors), a run of at most QP_MOTOR_TEST_MAX_MS, stopped by itself on a mode change, on lift, after
 * QP_MOTOR_TEST_LINK_MS of silence from the terminal, or by a command with level 0; each stop says
 * Event(MOTOR_TEST, why). The board calls qb_motortest_apply from its control task, after its own motor commands.
 */
#ifndef QB_CONSOLE_H
#define QB_CONSOLE_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

struct qb_board;

#define QB_LOG_MAX 64

typedef struct {
    uint8_t on, mask;
    uint16_t level;
    uint64_t until_us;
} qb_motortest_t;

/* A debug line to the terminal (see above); returns 1 if sent, 0 if dropped. */
int qb_log(struct qb_board *b, uint8_t level, const char *fmt, ...);
/* The formatter qb_log uses: at most cap - 1 characters and a NUL; returns the length written. */
size_t qb_vformat(char *out, size_t cap, const char *fmt, va_list ap);

/* Op.MOTOR_TEST's handler: the Nak; *value the level now running. */
uint8_t qb_motortest_command(struct qb_board *b, int32_t arg, int32_t *value);
/* In the control task after the board's own motor commands: while a test runs, its commands replace them. */
void qb_motortest_apply(struct qb_board *b, uint16_t ae[4]);

#endif /* QB_CONSOLE_H */
