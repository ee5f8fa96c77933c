/* A harness for qb_log alone (firmware/board/qb_console.c): the hardware layer's UART is a buffer, the board a
 * zeroed qb_board_t; each call's frames are printed as one hex line ("-" when the line was dropped). The C half of
 * tests/firmware/test_qb_log.py. */
#include <stdio.h>
#include <string.h>

#include "qb_board.h"
#include "qb_console.h"

static uint8_t wire[4096];
static size_t wire_len, wire_cap = sizeof wire;

size_t hal_uart_write(const uint8_t *data, size_t len)
{
    if (wire_len + len > wire_cap)
        return 0;
    memcpy(wire + wire_len, data, len);
    wire_len += len;
    return len;
}

/* what qb_console.c's motor test calls (not used here) */
int32_t qb_modes_lift(const qb_modes_t *m) { (void)m; return 0; }
uint64_t qb_link_silent_us(qb_board_t *b) { (void)b; return 0; }

static qb_board_t board;

static void out(int sent)
{
    size_t i;
    if (!sent) {
        printf("-\n");
    } else {
        for (i = 0; i < wire_len; i++)
            printf("%02x", wire[i]);
        printf("\n");
    }
    wire_len = 0;
}

int main(void)
{
    memset(&board, 0, sizeof board);
    out(qb_log(&board, 2, "hello"));
    out(qb_log(&board, 4, "imu: %s after %d tries (%u%%)", "timeout", -3, 42u));
    out(qb_log(&board, 1, "x=%x c=%c long=%ld s=%s", 0xBEEFu, 'Q', -1234567L, (const char *)0));
    out(qb_log(&board, 3, "%s", "0123456789012345678901234567890123456789012345678901234567890123456789"));
    out(qb_log(&board, 2, ""));
    out(qb_log(&board, 2, "odd %q %"));
    wire_cap = 10; /* a full queue: the whole line is dropped, the sequence numbers untouched */
    out(qb_log(&board, 2, "dropped line"));
    wire_cap = sizeof wire;
    out(qb_log(&board, 2, "after"));
    printf("sent %u dropped %u\n", (unsigned)board.log_sent, (unsigned)board.log_dropped);
    return 0;
}
