/* qb_log.c: the flash log, fcb_sim/board/flash_log.py in C: segments of compressed records in NOR flash (through
 * hal_flash_*), the report's delta8 and our Rice code (docs/flash_log.md), the same bytes as the Python board's
 * encoder for the same records (tests/firmware/test_cboard_log.py), and the download in chunks.
 *
 * Below the codec, the board's side: the logging task (one record per control step), LogStatus and the download.
 *
 * The encoder mirrors term/core/logformat.py's decoder state machines; Python's integers are unbounded, so every
 * sum that may pass 32 bits is 64 bits here (a residual of two int32 values, the Rice statistics). */
#include <math.h>
#include <string.h>

#include "hal.h"
#include "qb_board.h"

/* term/core/logformat.py and fcb_sim/board/flash_log.py (LOG_VARS); the test checks they are still those. */
#define LOG_FORMAT_VERSION 2u
#define RICE_ESCAPE 20
#define RICE_RESET 64
#define HEADER_BYTES 14u
#define VAR_BYTES 12u
#define SEGMENT_HEADER_BYTES (HEADER_BYTES + VAR_BYTES * QB_LOG_VARS)

static const char VAR_NAMES[QB_LOG_VARS][9] = {"t_us", "mode", "phi", "theta", "psi", "sp", "sq", "sr", "sax",
                                               "say", "saz", "ae1", "ae2", "ae3", "ae4", "height", "pressure",
                                               "battery"};
static const uint8_t VAR_SCALES[QB_LOG_VARS] = {32, 1, 2, 2, 2, 4, 4, 4, 8, 8, 8, 1, 1, 1, 1, 1, 1, 1};

/* A NOR flash without an erase function in its HAL (hal_m0.c until a team writes one): LOG_RESET cannot erase. */
__attribute__((weak)) int hal_flash_erase(uint32_t addr, size_t len)
{
    (void)addr;
    (void)len;
    return -1;
}

/* --- bits (flash_log.BitWriter): MSB first, complete bytes out as they fill -------------------------------- */

typedef struct {
    qb_log_t *log;
    uint8_t out[QB_LOG_RECORD_MAX];
    size_t n;
} bits_t;

static void put_bits(bits_t *w, uint32_t value, unsigned nbits)
{
    qb_log_t *l = w->log;
    if (nbits == 0)
        return;
    l->acc = (l->acc << nbits) | (nbits < 32 ? value & ((1u << nbits) - 1u) : value);
    l->nbits = (uint8_t)(l->nbits + nbits);
    while (l->nbits >= 8) {
        l->nbits = (uint8_t)(l->nbits - 8);
        w->out[w->n++] = (uint8_t)(l->acc >> l->nbits);
    }
    l->acc &= (1u << l->nbits) - 1u;
}

static void put_bits64(bits_t *w, uint64_t value, unsigned nbits)
{
    if (nbits > 32) {
        put_bits(w, (uint32_t)(value >> 32), nbits - 32);
        nbits = 32;
    }
    put_bits(w, (uint32_t)value, nbits);
}

/* --- flash (flash_log.Flash): programming ANDs bits in ------------------------------------------------------ */

static void program(qb_log_t *l, const uint8_t *data, size_t n)
{
    if (n && hal_flash_write(l->used, data, n) != 0)
        l->flash_errors++;
    l->used += (uint32_t)n;
}

/* --- the codecs ---------------------------------------------------------------------------------------------- */

/* Python's a // b for b > 0, in unsigned division (the M0 then links one 64-bit divide, not two) */
static int64_t floor_div(int64_t a, uint32_t b)
{
    return a >= 0 ? (int64_t)((uint64_t)a / b) : -(int64_t)(((uint64_t)-(a + 1) + b) / b);
}

/* logformat.quantise: the nearest multiple's index (ties up) */
static int64_t quantise(int64_t x, uint32_t scale)
{
    return floor_div(x + (int64_t)(scale / 2u), scale);
}

static uint64_t zigzag(int64_t r)
{
    return r >= 0 ? 2u * (uint64_t)r : 2u * (uint64_t)(-(r + 1)) + 1u;
}

static int64_t rice_predict(const qb_rice_t *st)
{
    return st->e1 <= st->e2 ? st->prev1 : 2 * (int64_t)st->prev1 - st->prev2;
}

static unsigned rice_k(const qb_rice_t *st)
{
    unsigned k = 0;
    while (((int64_t)st->n << k) < st->a)
        k++;
    return k;
}

static void rice_update(qb_rice_t *st, int64_t q, uint64_t z)
{
    int64_t p1 = st->prev1, p2 = 2 * (int64_t)st->prev1 - st->prev2, d1 = q - p1, d2 = q - p2;
    st->e1 += (d1 < 0 ? -d1 : d1) - (st->e1 >> 4);
    st->e2 += (d2 < 0 ? -d2 : d2) - (st->e2 >> 4);
    st->prev2 = st->prev1;
    st->prev1 = (int32_t)q;
    st->a += (int64_t)z;
    st->n++;
    if (st->n >= RICE_RESET) {
        st->a = st->a >> 1 > 1 ? st->a >> 1 : 1;
        st->n >>= 1;
    }
}

/* The worst bytes one record may add (RecordEncoder.worst_bytes: the flash-full check). */
static uint32_t worst_bytes(uint8_t scheme)
{
    if (scheme == QB_SCHEME_DELTA8)
        return 4u * QB_LOG_VARS;
    return (QB_LOG_VARS * (RICE_ESCAPE + 32 + 40) + 7) / 8 + 1;
}

static void encode(qb_log_t *l, const int64_t v[QB_LOG_VARS], bits_t *w)
{
    int i;
    if (l->count == 0) { /* the first record is absolute (int32 each): both schemes start from the true values */
        for (i = 0; i < QB_LOG_VARS; i++) {
            put_bits(w, (uint32_t)v[i], 32);
            l->recon[i] = v[i];
            if (l->scheme == QB_SCHEME_RICE) {
                qb_rice_t *st = &l->rice[i];
                st->prev1 = st->prev2 = (int32_t)quantise(v[i], VAR_SCALES[i]);
                st->e1 = st->e2 = 0;
                st->a = 4;
                st->n = 1;
            }
        }
    } else if (l->scheme == QB_SCHEME_DELTA8) {
        for (i = 0; i < QB_LOG_VARS; i++) {
            int64_t q = quantise(v[i] - l->recon[i], VAR_SCALES[i]);
            q = q < -127 ? -127 : q > 127 ? 127 : q;
            l->recon[i] += q * VAR_SCALES[i]; /* the error term: the next delta from what the decoder holds */
            put_bits(w, (uint32_t)q & 0xFFu, 8);
        }
    } else {
        for (i = 0; i < QB_LOG_VARS; i++) {
            qb_rice_t *st = &l->rice[i];
            int64_t q = quantise(v[i], VAR_SCALES[i]);
            uint64_t z = zigzag(q - rice_predict(st));
            unsigned k = rice_k(st);
            uint64_t top = k < 64 ? z >> k : 0;
            if (top < RICE_ESCAPE) {
                put_bits(w, ((1u << top) - 1u) << 1, (unsigned)top + 1u); /* unary: top ones and a zero */
                if (k)
                    put_bits64(w, k < 64 ? z & ((1ull << k) - 1u) : z, k);
            } else {
                put_bits(w, (1u << RICE_ESCAPE) - 1u, RICE_ESCAPE);
                put_bits(w, (uint32_t)z, 32);
            }
            rice_update(st, q, z);
        }
    }
    l->count++;
}

/* --- the logger (flash_log.FlashLog) ------------------------------------------------------------------------- */

void qb_log_init(qb_log_t *l, uint32_t size, uint8_t scheme)
{
    memset(l, 0, sizeof *l);
    l->size = size;
    l->scheme = scheme;
    l->state = QP_LOG_STATE_IDLE;
}

uint8_t qb_log_start(qb_log_t *l)
{
    uint8_t head[SEGMENT_HEADER_BYTES];
    int i;
    if (l->state == QP_LOG_STATE_RECORDING)
        return QP_NAK_OK;
    if (l->used + SEGMENT_HEADER_BYTES + worst_bytes(l->scheme) > l->size) {
        l->state = QP_LOG_STATE_FULL;
        return QP_NAK_LOG_FULL;
    }
    memset(head, 0xFF, sizeof head); /* the record count and length stay erased until the segment closes */
    head[0] = 'Q';
    head[1] = 'L';
    head[2] = LOG_FORMAT_VERSION;
    head[3] = l->scheme;
    head[4] = QB_LOG_VARS;
    for (i = 0; i < QB_LOG_VARS; i++) {
        uint8_t *e = head + HEADER_BYTES + VAR_BYTES * (unsigned)i;
        memset(e, 0, 8);
        memcpy(e, VAR_NAMES[i], strlen(VAR_NAMES[i]));
        e[8] = VAR_SCALES[i];
        e[9] = 0;
    }
    l->seg_start = l->used;
    program(l, head, sizeof head);
    l->data_start = l->used;
    l->seg_records = 0;
    l->count = 0;
    l->acc = 0;
    l->nbits = 0;
    l->state = QP_LOG_STATE_RECORDING;
    return QP_NAK_OK;
}

static uint32_t close_segment(qb_log_t *l, uint8_t state)
{
    bits_t w;
    uint8_t fields[8];
    uint32_t len, before = l->used;
    w.log = l;
    w.n = 0;
    if (l->nbits) /* the last partial byte, padded with 1 bits (erased flash) */
        put_bits(&w, (1u << (8u - l->nbits)) - 1u, 8u - l->nbits);
    program(l, w.out, w.n);
    len = l->used - l->data_start;
    fields[0] = (uint8_t)l->seg_records;
    fields[1] = (uint8_t)(l->seg_records >> 8);
    fields[2] = (uint8_t)(l->seg_records >> 16);
    fields[3] = (uint8_t)(l->seg_records >> 24);
    fields[4] = (uint8_t)len;
    fields[5] = (uint8_t)(len >> 8);
    fields[6] = (uint8_t)(len >> 16);
    fields[7] = (uint8_t)(len >> 24);
    if (hal_flash_write(l->seg_start + 6u, fields, sizeof fields) != 0)
        l->flash_errors++;
    l->state = state;
    return l->used - before + (uint32_t)sizeof fields;
}

uint32_t qb_log_append(qb_log_t *l, const int64_t values[QB_LOG_VARS])
{
    bits_t w;
    uint32_t before = l->used;
    if (l->state != QP_LOG_STATE_RECORDING)
        return 0;
    if (l->used + worst_bytes(l->scheme) + 1u > l->size)
        return close_segment(l, QP_LOG_STATE_FULL);
    w.log = l;
    w.n = 0;
    encode(l, values, &w);
    program(l, w.out, w.n);
    l->seg_records++;
    l->records++;
    return l->used - before;
}

uint8_t qb_log_stop(qb_log_t *l)
{
    if (l->state == QP_LOG_STATE_RECORDING)
        close_segment(l, QP_LOG_STATE_IDLE);
    return QP_NAK_OK;
}

uint8_t qb_log_reset(qb_log_t *l, int in_safe)
{
    if (!in_safe)
        return QP_NAK_NOT_IN_SAFE;
    if (l->state == QP_LOG_STATE_RECORDING || l->dl_active)
        return QP_NAK_LOG_BUSY;
    if (hal_flash_erase(0, l->size) != 0)
        return QP_NAK_NOT_IMPLEMENTED; /* a HAL that cannot erase its flash */
    l->used = l->records = 0;
    l->state = QP_LOG_STATE_IDLE;
    return QP_NAK_OK;
}

uint32_t qb_log_chunks(const qb_log_t *l)
{
    return (l->used + QB_LOG_CHUNK - 1u) / QB_LOG_CHUNK;
}

void qb_log_chunk(const qb_log_t *l, uint32_t index, uint8_t out[QB_LOG_CHUNK])
{
    uint32_t start = index * QB_LOG_CHUNK, n = start < l->used ? l->used - start : 0;
    memset(out, 0xFF, QB_LOG_CHUNK);
    if (n > QB_LOG_CHUNK)
        n = QB_LOG_CHUNK;
    if (n && hal_flash_read(start, out, n) != 0)
        memset(out, 0xFF, QB_LOG_CHUNK);
}

/* zlib's CRC-32 of the used flash, a nibble at a time (a 64-byte table) */
uint32_t qb_log_crc32(const qb_log_t *l)
{
    static const uint32_t T[16] = {0x00000000u, 0x1db71064u, 0x3b6e20c8u, 0x26d930acu, 0x76dc4190u, 0x6b6b51f4u,
                                   0x4db26158u, 0x5005713cu, 0xedb88320u, 0xf00f9344u, 0xd6d6a3e8u, 0xcb61b38cu,
                                   0x9b64c2b0u, 0x86d3d2d4u, 0xa00ae278u, 0xbdbdf21cu};
    uint8_t buf[64];
    uint32_t crc = 0xFFFFFFFFu, pos, i;
    for (pos = 0; pos < l->used; pos += sizeof buf) {
        uint32_t n = l->used - pos < sizeof buf ? l->used - pos : (uint32_t)sizeof buf;
        if (hal_flash_read(pos, buf, n) != 0)
            memset(buf, 0xFF, n);
        for (i = 0; i < n; i++) {
            crc ^= buf[i];
            crc = (crc >> 4) ^ T[crc & 15u];
            crc = (crc >> 4) ^ T[crc & 15u];
        }
    }
    return crc ^ 0xFFFFFFFFu;
}

/* --- the board's side: the logging task, LogStatus, the download (qb_board.c's tasks and commands call them) -- */

void qb_log_send_status(qb_board_t *b, uint8_t state)
{
    qp_packet_t p;
    p.type = QP_TYPE_LOG_STATUS;
    p.u.log_status.state = state;
    p.u.log_status.used = b->log.used;
    p.u.log_status.records = b->log.records;
    p.u.log_status.crc32 = qb_log_crc32(&b->log);
    qb_send(b, &p);
}

/* The download stops (done, or the board left SAFE) and says where the log stands (flash_log.Download.end). */
void qb_log_end_download(qb_board_t *b)
{
    b->log.dl_active = 0;
    qb_log_send_status(b, b->log.state);
    qb_send_event(b, QP_EVENT_CODE_LOG_DONE, (int32_t)b->log.dl_sent);
}

void qb_log_begin_download(qb_board_t *b, uint32_t first)
{
    b->log.dl_active = 1;
    b->log.dl_next = first;
    b->log.dl_sent = 0;
    qb_log_send_status(b, QP_LOG_STATE_DOWNLOADING);
}

/* One telemetry run of a download: chunks in order, QB_DOWNLOAD_CHUNKS_PER_RUN at most (flash_log.Download.step). */
void qb_log_download_step(qb_board_t *b)
{
    qp_packet_t p;
    unsigned k;
    uint32_t n = qb_log_chunks(&b->log);
    for (k = 0; k < QB_DOWNLOAD_CHUNKS_PER_RUN && b->log.dl_active; k++) {
        p.type = QP_TYPE_LOG_CHUNK;
        p.u.log_chunk.index = (uint16_t)b->log.dl_next;
        qb_log_chunk(&b->log, b->log.dl_next, p.u.log_chunk.data);
        qb_send(b, &p);
        b->log.dl_sent++;
        if (++b->log.dl_next >= n)
            qb_log_end_download(b);
    }
}

/* Python's round(): half to even (the log's columns are the Python board's to the bit); through int32, which the
 * columns fit (a float to int64 conversion would link the M0's soft double routines) */
static int32_t round_even(qb_real v)
{
    qb_real r = QM(floor)(v + 0.5);
    r = r < -2147483648.0 ? -2147483648.0 : r > 2147483520.0 ? 2147483520.0 : r;
    if (r - v == 0.5 && ((int32_t)r & 1))
        r -= 1.0;
    return (int32_t)r;
}

/* One record per control step while logging (fcb_sim's Board._task_logging: the same columns in board units). */
void qb_log_task(qb_board_t *b)
{
    const qb_flight_t *fc = &b->core;
    int64_t row[QB_LOG_VARS];
    int32_t att[3];
    int i;
    qb_flight_attitude_cdeg(fc, att);
    row[0] = (int64_t)b->now;
    row[1] = b->modes.mode;
    row[2] = att[0];
    row[3] = att[1];
    row[4] = att[2];
    row[5] = round_even(fc->sp);
    row[6] = round_even(fc->sq);
    row[7] = round_even(fc->sr);
    row[8] = round_even(fc->sax);
    row[9] = round_even(fc->say);
    row[10] = round_even(fc->saz);
    for (i = 0; i < 4; i++)
        row[11 + i] = b->ae[i];
    row[15] = round_even(fc->height / 0.01);
    row[16] = b->pressure;
    row[17] = b->battery;
    qb_log_append(&b->log, row);
    if (b->log.state == QP_LOG_STATE_FULL && !b->log.full_reported) {
        b->log.full_reported = 1;
        qb_send_event(b, QP_EVENT_CODE_LOG_FULL, (int32_t)b->log.used);
    }
}
