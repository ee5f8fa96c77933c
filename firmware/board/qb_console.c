/* qb_console.c: qb_log (the board's debug lines as Text packets) and the bench motor test; see qb_console.h. */
#include "qb_console.h"

#include <string.h>

#include "hal.h"
#include "qb_board.h"

/* --- qb_log ------------------------------------------------------------------------------------------------- */

static size_t put_u(char *out, size_t n, size_t cap, unsigned long v, unsigned base)
{
    char digits[24];
    size_t k = 0;
    do {
        unsigned d = (unsigned)(v % base);
        digits[k++] = (char)(d < 10 ? '0' + d : 'a' + d - 10);
        v /= base;
    } while (v && k < sizeof digits);
    while (k && n + 1 < cap)
        out[n++] = digits[--k];
    return n;
}

size_t qb_vformat(char *out, size_t cap, const char *fmt, va_list ap)
{
    size_t n = 0;
    if (cap == 0)
        return 0;
    for (; *fmt && n + 1 < cap; fmt++) {
        int is_long = 0;
        if (*fmt != '%') {
            out[n++] = *fmt;
            continue;
        }
        fmt++;
        while (*fmt == 'l') {
            is_long = 1;
            fmt++;
        }
        switch (*fmt) {
        case 'd':
        case 'i': {
            long v = is_long ? va_arg(ap, long) : va_arg(ap, int);
            unsigned long u = v < 0 ? 0ul - (unsigned long)v : (unsigned long)v;
            if (v < 0)
                out[n++] = '-';
            n = put_u(out, n, cap, u, 10);
            break;
        }
        case 'u':
            n = put_u(out, n, cap, is_long ? va_arg(ap, unsigned long) : va_arg(ap, unsigned), 10);
            break;
        case 'x':
            n = put_u(out, n, cap, is_long ? va_arg(ap, unsigned long) : va_arg(ap, unsigned), 16);
            break;
        case 'c':
            out[n++] = (char)va_arg(ap, int);
            break;
        case 's': {
            const char *s = va_arg(ap, const char *);
            for (s = s ? s : "(null)"; *s && n + 1 < cap; s++)
                out[n++] = *s;
            break;
        }
        case '%':
            out[n++] = '%';
            break;
        case '\0':
            fmt--; /* a lone % at the end */
            break;
        default: /* not ours: shown as written */
            out[n++] = '%';
            if (n + 1 < cap)
                out[n++] = *fmt;
            break;
        }
    }
    out[n] = '\0';
    return n;
}

int qb_log(struct qb_board *b, uint8_t level, const char *fmt, ...)
{
    char line[QB_LOG_MAX + 1];
    uint8_t frames[((QB_LOG_MAX + QP_TEXT_BYTES - 1) / QP_TEXT_BYTES) * QP_MAX_FRAME];
    size_t len, off = 0, used = 0, n;
    qp_encoder_t enc = b->enc; /* the sequence numbers advance only if the line goes out */
    qp_packet_t p;
    va_list ap;
    va_start(ap, fmt);
    len = qb_vformat(line, sizeof line, fmt, ap);
    va_end(ap);
    p.type = QP_TYPE_TEXT;
    do {
        size_t take = len - off < QP_TEXT_BYTES ? len - off : QP_TEXT_BYTES;
        memset(p.u.text.text, 0, sizeof p.u.text.text);
        memcpy(p.u.text.text, line + off, take);
        off += take;
        p.u.text.info = (uint8_t)((level & QP_TEXT_LEVEL_MASK) | (off < len ? QP_TEXT_MORE : 0u));
        n = qp_encode(&enc, &p, frames + used);
        used += n;
    } while (off < len);
    if (hal_uart_write(frames, used) != used) { /* the queue is full: the whole line is dropped */
        b->log_dropped++;
        return 0;
    }
    b->enc = enc;
    b->log_sent++;
    return 1;
}

/* --- the motor test ----------------------------------------------------------------------------------------- */

static void motortest_stop(struct qb_board *b, uint8_t why)
{
    qb_modes_t *m = &b->modes;
    memset(&b->mt, 0, sizeof b->mt);
    if (m->n_events < QB_EVENTS) { /* said with the mode machine's events (the board drains them) */
        m->events[m->n_events].code = QP_EVENT_CODE_MOTOR_TEST;
        m->events[m->n_events].arg = why;
        m->n_events++;
    }
}

uint8_t qb_motortest_command(struct qb_board *b, int32_t arg, int32_t *value)
{
    qb_modes_t *m = &b->modes;
    uint32_t mask = ((uint32_t)arg >> 16) & 0xFFu, level = (uint32_t)arg & 0xFFFFu;
    *value = b->mt.on ? b->mt.level : 0;
    if (level == 0 || mask == 0) {
        if (b->mt.on)
            motortest_stop(b, QP_MOTOR_TEST_END_STOPPED);
        *value = 0;
        return QP_NAK_OK;
    }
    if (m->mode != QP_MODE_SAFE)
        return QP_NAK_NOT_IN_SAFE;
    if (m->crashed)
        return QP_NAK_CRASHED;
    if (qb_modes_lift(m) > QP_LIFT_ZERO)
        return QP_NAK_LIFT_NOT_ZERO;
    if (mask & ~0xFu)
        return QP_NAK_BAD_ARGUMENT;
    if (level > QP_MOTOR_TEST_MAX_LEVEL)
        return QP_NAK_OUT_OF_RANGE;
    b->mt.on = 1;
    b->mt.mask = (uint8_t)mask;
    b->mt.level = (uint16_t)level;
    b->mt.until_us = b->now + (uint64_t)QP_MOTOR_TEST_MAX_MS * 1000u;
    *value = (int32_t)level;
    qb_log(b, 2, "motor test: mask %x at %u for %u ms", mask, level, (unsigned)QP_MOTOR_TEST_MAX_MS);
    return QP_NAK_OK;
}

void qb_motortest_apply(struct qb_board *b, uint16_t ae[4])
{
    qb_modes_t *m = &b->modes;
    int i;
    if (!b->mt.on)
        return;
    if (m->mode != QP_MODE_SAFE)
        motortest_stop(b, QP_MOTOR_TEST_END_MODE);
    else if (qb_modes_lift(m) > QP_LIFT_ZERO)
        motortest_stop(b, QP_MOTOR_TEST_END_LIFT);
    else if (qb_link_silent_us(b) >= (uint64_t)QP_MOTOR_TEST_LINK_MS * 1000u)
        motortest_stop(b, QP_MOTOR_TEST_END_LINK_SILENT);
    else if (b->now >= b->mt.until_us)
        motortest_stop(b, QP_MOTOR_TEST_END_TIME_UP);
    if (!b->mt.on)
        return;
    for (i = 0; i < 4; i++)
        ae[i] = (b->mt.mask >> i) & 1u ? b->mt.level : 0;
}
