/* host_board.c: the reference board, built for this computer. The template a firmware team starts from.
 *
 * It speaks the protocol over a serial device as the Quadrupel board does over its UART, with the parts of a
 * flight controller that talk to the terminal and nothing else (no sensors, no motors):
 *   - at boot, a Hello (protocol version, role, software version, board id) and an Event BOOT; a terminal's
 *     Hello (it connected, or reconnected) is answered with ours;
 *   - a Heartbeat every 100 ms, carrying the round trip of the previous one (measured from its HeartbeatAck),
 *     and an Attitude packet with the mode (the terminal shows the mode from it; the angles are zero here);
 *   - every Command answered by one Ack: MODE SAFE and MODE PANIC are accepted, everything else is refused with
 *     Nak NOT_IMPLEMENTED ("not implemented on this board"); a retry of the last command (the same id, op and
 *     arg within 2 s: its Ack was lost) is answered again, not executed twice;
 *   - Joystick frames counted; the fire button is PANIC;
 *   - link silence: no valid frame for LINK_TIMEOUT_US after the terminal was heard means PANIC; PANIC holds
 *     the motors for PANIC_HOLD_US, then SAFE. Every mode change is an Event.
 *
 * Usage: host_board --pty     a fresh pseudo-terminal; the first line on stdout is "pty: /dev/pts/N"
 *        host_board DEVICE    a serial device (115200 baud 8N1, raw)
 * SIGTERM or SIGINT end it cleanly: a summary line on stdout, exit status 0.
 *
 * On the real board the POSIX parts (marked EDGE) are the firmware's: now_us() reads a timer, the UART receive
 * interrupt feeds qp_decode_byte() (or a ring buffer that the main loop hands to qp_decode()), send_frame()
 * writes the UART (or a BLE notification: a frame is at most 20 bytes), and main() is the main loop.
 */
#define _XOPEN_SOURCE 600

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "qp_protocol.h"

#define BOARD_MAJOR 0
#define BOARD_MINOR 1
#define BOARD_ID 4242
#define HEARTBEAT_US 100000u
#define LINK_TIMEOUT_US 500000u
#define PANIC_HOLD_US 1000000u
#define DEDUPE_US 2000000u

struct board {
    int fd;
    qp_encoder_t enc;     /* our frames: sequence numbers and counts */
    qp_decoder_t dec;     /* the terminal's byte stream */
    uint8_t mode;
    uint64_t boot_us;
    uint64_t next_heartbeat_us;
    uint64_t panic_since_us;
    uint64_t last_frame_us;  /* the last valid frame from the terminal */
    int heard;               /* a valid frame arrived since boot or the last link timeout */
    uint16_t heartbeats;
    uint64_t heartbeat_sent_us;
    uint16_t rtt;            /* the last heartbeat's round trip, 0.1 ms; 0: no answer to the last one */
    int have_last;           /* last_cmd and last_ack hold the last command and its answer */
    qp_command_t last_cmd;
    qp_ack_t last_ack;
    uint64_t last_cmd_us;
    uint8_t buttons;
    unsigned long joysticks, commands, tx_dropped;
};

static volatile sig_atomic_t stop_requested;

/* --- EDGE: time and bytes out ---------------------------------------------------------------------------- */

static uint64_t now_us(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000u + (uint64_t)t.tv_nsec / 1000u;
}

static void send_frame(struct board *b, const uint8_t *frame, size_t n)
{
    ssize_t w = write(b->fd, frame, n);  /* non-blocking: like a UART nobody reads, what does not fit is lost */
    if (w < (ssize_t)n)
        b->tx_dropped += n - (size_t)(w > 0 ? w : 0);
}

/* --- packets out ------------------------------------------------------------------------------------------ */

static uint32_t board_ms(const struct board *b)
{
    return (uint32_t)((now_us() - b->boot_us) / 1000u);
}

static void send_hello(struct board *b)
{
    uint8_t frame[QP_MAX_FRAME];
    qp_hello_t hello;
    hello.protocol = QP_PROTOCOL_VERSION;
    hello.role = QP_ROLE_BOARD;
    hello.major = BOARD_MAJOR;
    hello.minor = BOARD_MINOR;
    hello.board_id = BOARD_ID;
    send_frame(b, frame, qp_encode_hello(&b->enc, &hello, frame));
}

static void send_event(struct board *b, uint8_t code, int32_t arg)
{
    uint8_t frame[QP_MAX_FRAME];
    qp_event_t ev;
    ev.code = code;
    ev.arg = arg;
    ev.board_ms = board_ms(b);
    send_frame(b, frame, qp_encode_event(&b->enc, &ev, frame));
}

static void send_heartbeat(struct board *b, uint64_t now)
{
    uint8_t frame[QP_MAX_FRAME];
    qp_heartbeat_t hb;
    qp_attitude_t att;
    hb.counter = ++b->heartbeats;
    hb.board_ms = board_ms(b);
    hb.rtt = b->rtt;  /* the previous heartbeat's round trip, if its ack came back */
    b->rtt = 0;
    b->heartbeat_sent_us = now;
    send_frame(b, frame, qp_encode_heartbeat(&b->enc, &hb, frame));
    memset(&att, 0, sizeof att);
    att.mode = b->mode;
    send_frame(b, frame, qp_encode_attitude(&b->enc, &att, frame));
}

static void set_mode(struct board *b, uint8_t mode, uint64_t now)
{
    uint8_t old = b->mode;
    if (mode == old)
        return;
    b->mode = mode;
    if (mode == QP_MODE_PANIC)
        b->panic_since_us = now;
    send_event(b, QP_EVENT_CODE_MODE_CHANGED, (int32_t)((old << 8) | mode));
}

/* --- packets in ------------------------------------------------------------------------------------------- */

/* Do a command; returns the Nak (QP_NAK_OK: done) and sets *value to what the Ack reports. */
static uint8_t execute(struct board *b, const qp_command_t *cmd, uint64_t now, int32_t *value)
{
    uint8_t status = QP_NAK_NOT_IMPLEMENTED;
    if (cmd->op == QP_OP_MODE && cmd->arg == QP_MODE_PANIC) {
        /* PANIC is always accepted. A flying board enters it from a flight mode and in SAFE has nothing to do
         * (its motors are off); this one has no motors, so it enters PANIC from SAFE too, to show the path. */
        set_mode(b, QP_MODE_PANIC, now);
        status = QP_NAK_OK;
    } else if (cmd->op == QP_OP_MODE && cmd->arg == QP_MODE_SAFE) {
        status = b->mode == QP_MODE_PANIC ? QP_NAK_PANIC_ACTIVE : QP_NAK_OK;  /* PANIC ends in SAFE by itself */
        if (status == QP_NAK_OK)
            set_mode(b, QP_MODE_SAFE, now);
    }
    *value = b->mode;
    return status;
}

static void on_command(struct board *b, const qp_command_t *cmd, uint64_t now)
{
    uint8_t frame[QP_MAX_FRAME];
    int32_t value;
    int retry = b->have_last && cmd->cmd_id == b->last_cmd.cmd_id && cmd->op == b->last_cmd.op &&
                cmd->arg == b->last_cmd.arg && now - b->last_cmd_us < DEDUPE_US;
    if (!retry) {
        b->commands++;
        b->last_ack.status = execute(b, cmd, now, &value);
        b->last_ack.cmd_id = cmd->cmd_id;
        b->last_ack.op = cmd->op;
        b->last_ack.value = value;
        b->last_cmd = *cmd;
        b->last_cmd_us = now;
        b->have_last = 1;
    }
    send_frame(b, frame, qp_encode_ack(&b->enc, &b->last_ack, frame));
}

static void on_packet(void *ctx, const qp_packet_t *pkt)
{
    struct board *b = ctx;
    uint64_t now = now_us();
    b->last_frame_us = now;
    b->heard = 1;
    switch (pkt->type) {
    case QP_TYPE_JOYSTICK:
        b->joysticks++;
        if ((pkt->u.joystick.buttons & QP_BUTTON_FIRE) && !(b->buttons & QP_BUTTON_FIRE))
            set_mode(b, QP_MODE_PANIC, now);  /* on the press, not while it is held */
        b->buttons = pkt->u.joystick.buttons;
        break;
    case QP_TYPE_COMMAND:
        on_command(b, &pkt->u.command, now);
        break;
    case QP_TYPE_HEARTBEAT_ACK:
        if (pkt->u.heartbeat_ack.counter == b->heartbeats) {
            uint64_t rtt = (now - b->heartbeat_sent_us) / 100u;
            b->rtt = (uint16_t)(rtt < 1 ? 1 : rtt > 0xFFFF ? 0xFFFF : rtt);
        }
        break;
    case QP_TYPE_HELLO:
        /* A terminal (re)connected: its sequence numbers and command ids start afresh. */
        if (!qp_hello_compatible(&pkt->u.hello))
            fprintf(stderr, "host_board: the terminal speaks protocol v%u, this board v%u\n",
                    pkt->u.hello.protocol, QP_PROTOCOL_VERSION);
        qp_decoder_reset_sequence(&b->dec);
        b->have_last = 0;
        send_hello(b);
        break;
    default:
        break;  /* a board-to-PC packet echoed back, or one this board does not use */
    }
}

/* --- the periodic part of the main loop --------------------------------------------------------------------- */

static void tick(struct board *b, uint64_t now)
{
    if (now >= b->next_heartbeat_us) {
        send_heartbeat(b, now);
        b->next_heartbeat_us += HEARTBEAT_US;
        if (b->next_heartbeat_us <= now)  /* woken far too late: a new grid, not a burst */
            b->next_heartbeat_us = now + HEARTBEAT_US;
    }
    if (b->heard && now - b->last_frame_us > LINK_TIMEOUT_US) {
        /* A flying board does this in a flight mode (QP_IS_FLIGHT_MODE); without motors, every mode shows it. */
        b->heard = 0;
        send_event(b, QP_EVENT_CODE_LINK_TIMEOUT, (int32_t)((now - b->last_frame_us) / 1000u));
        set_mode(b, QP_MODE_PANIC, now);
    }
    if (b->mode == QP_MODE_PANIC && now - b->panic_since_us >= PANIC_HOLD_US) {
        send_event(b, QP_EVENT_CODE_PANIC_DONE, 0);
        set_mode(b, QP_MODE_SAFE, now);
    }
}

/* --- EDGE: the serial device ------------------------------------------------------------------------------ */

static void on_signal(int sig)
{
    (void)sig;
    stop_requested = 1;
}

static int make_raw(int fd, int set_speed)
{
    struct termios t;
    if (tcgetattr(fd, &t) != 0)
        return -1;
    t.c_iflag &= ~(tcflag_t)(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON | IXOFF);
    t.c_oflag &= ~(tcflag_t)OPOST;
    t.c_lflag &= ~(tcflag_t)(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
    t.c_cflag &= ~(tcflag_t)(CSIZE | PARENB | CSTOPB);
    t.c_cflag |= CS8 | CLOCAL | CREAD;
    t.c_cc[VMIN] = 1;
    t.c_cc[VTIME] = 0;
    if (set_speed && (cfsetispeed(&t, B115200) != 0 || cfsetospeed(&t, B115200) != 0))
        return -1;
    return tcsetattr(fd, TCSANOW, &t);
}

/* A fresh pseudo-terminal: returns the master; *slave stays open here so the master never sees a hang-up
 * between two terminals (as fcb-sim serve --pty does). */
static int open_pty(int *slave)
{
    const char *path;
    int master = posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || grantpt(master) != 0 || unlockpt(master) != 0 || (path = ptsname(master)) == NULL)
        return -1;
    *slave = open(path, O_RDWR | O_NOCTTY);
    if (*slave < 0 || make_raw(*slave, 0) != 0)
        return -1;
    printf("pty: %s\n", path);
    fflush(stdout);
    return master;
}

int main(int argc, char **argv)
{
    static struct board board;
    struct board *b = &board;
    struct sigaction sa;
    int slave = -1;
    uint8_t buf[256];

    if (argc != 2 || argv[1][0] == '\0' || (argv[1][0] == '-' && strcmp(argv[1], "--pty") != 0)) {
        fprintf(stderr, "usage: host_board --pty | host_board DEVICE\n");
        return 2;
    }
    if (strcmp(argv[1], "--pty") == 0) {
        b->fd = open_pty(&slave);
    } else {
        b->fd = open(argv[1], O_RDWR | O_NOCTTY);
        if (b->fd >= 0 && make_raw(b->fd, 1) != 0) {
            close(b->fd);
            b->fd = -1;
        }
    }
    if (b->fd < 0 || fcntl(b->fd, F_SETFL, O_NONBLOCK) != 0) {
        fprintf(stderr, "host_board: cannot open %s: %s\n", argv[1], strerror(errno));
        return 1;
    }
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;  /* no SA_RESTART: poll() returns at once */
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);

    qp_decoder_init(&b->dec);
    b->mode = QP_MODE_SAFE;
    b->boot_us = now_us();
    b->next_heartbeat_us = b->boot_us + HEARTBEAT_US;
    send_hello(b);
    send_event(b, QP_EVENT_CODE_BOOT, QP_PROTOCOL_VERSION);

    while (!stop_requested) {
        uint64_t now = now_us();
        struct pollfd pfd;
        tick(b, now);
        pfd.fd = b->fd;
        pfd.events = POLLIN;
        if (poll(&pfd, 1, (int)((b->next_heartbeat_us - now + 999u) / 1000u)) > 0) {
            ssize_t n = read(b->fd, buf, sizeof buf);
            if (n > 0)
                qp_decode(&b->dec, buf, (size_t)n, on_packet, b);
            else if (n == 0 || (errno != EAGAIN && errno != EINTR && slave < 0))
                break;  /* the device went away (a USB adapter pulled) */
        }
    }
    printf("host_board: %s; %lu joystick frames, %lu commands, %lu frames ok, %lu damaged, %lu bytes dropped\n",
           b->mode == QP_MODE_PANIC ? "PANIC" : "SAFE", b->joysticks, b->commands,
           (unsigned long)b->dec.stats.frames_ok,
           (unsigned long)(b->dec.stats.crc_errors + b->dec.stats.malformed), b->tx_dropped);
    close(b->fd);
    if (slave >= 0)
        close(slave);
    return stop_requested ? 0 : 1;
}
