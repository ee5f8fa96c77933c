/* qp_runner: the C codec behind a line protocol on stdin/stdout, so Python tests can drive it over pipes and
 * compare it with term.core.protocol (tests/firmware/test_firmware.py) and bench/firmware.py can time it. Host only.
 *
 * Commands, one per line (HEX: bytes in hex; every answer ends with a line of its own):
 *   feed HEX               decode one slice     -> "pkt SEQ Name field=value ..." per packet, then "end STATS"
 *   bytes HEX              the same, byte by byte through qp_decode_byte
 *   reset / resetseq       a fresh decoder / qp_decoder_reset_sequence -> "ok"
 *   encode SEQ Name V...   one frame            -> "frame HEX" (or "error")
 *   crc HEX                                     -> "crc VALUE"
 *   h2f H...  / f2h F...   half <-> float, raw bits in hex -> "bits B..."
 *   bench REPEATS CHUNK HEX  decode HEX REPEATS times in CHUNK-byte slices -> "bench NANOSECONDS PACKETS"
 * STATS: frames_ok crc_errors malformed bytes_skipped seq_gaps bytes_in.
 */
#define _POSIX_C_SOURCE 199309L

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "qp_protocol.h"
#include "qp_text.h"

static qp_decoder_t dec;

static char *read_line(void)
{
    static char *line;
    static size_t cap;
    size_t n = 0;
    int c;
    while ((c = getchar()) != EOF && c != '\n') {
        if (n + 1 >= cap) {
            char *bigger = realloc(line, cap ? 2 * cap : 4096);
            if (!bigger)
                exit(3);
            line = bigger;
            cap = cap ? 2 * cap : 4096;
        }
        line[n++] = (char)c;
    }
    if (c == EOF && n == 0)
        return NULL;
    if (!line) {
        line = malloc(1);
        if (!line)
            exit(3);
    }
    line[n] = 0;
    return line;
}

/* Hex text to bytes; returns the byte count (the caller frees *out). */
static size_t unhex(const char *hex, uint8_t **out)
{
    size_t n = strlen(hex) / 2, i;
    *out = malloc(n ? n : 1);
    if (!*out)
        exit(3);
    for (i = 0; i < n; i++) {
        char pair[3] = {hex[2 * i], hex[2 * i + 1], 0};
        (*out)[i] = (uint8_t)strtoul(pair, NULL, 16);
    }
    return n;
}

static void on_packet(void *ctx, const qp_packet_t *pkt)
{
    (void)ctx;
    printf("pkt %u ", pkt->seq);
    qp_text_print(stdout, pkt);
    putchar('\n');
}

static void print_stats(void)
{
    const qp_decoder_stats_t *s = &dec.stats;
    printf("end %lu %lu %lu %lu %lu %lu\n", (unsigned long)s->frames_ok, (unsigned long)s->crc_errors,
           (unsigned long)s->malformed, (unsigned long)s->bytes_skipped, (unsigned long)s->seq_gaps,
           (unsigned long)s->bytes_in);
}

static void cmd_feed(const char *hex, int by_byte)
{
    uint8_t *data;
    size_t n = unhex(hex, &data), i;
    if (by_byte) {
        qp_packet_t pkt;
        for (i = 0; i < n; i++)
            if (qp_decode_byte(&dec, data[i], &pkt))
                on_packet(NULL, &pkt);
    } else {
        qp_decode(&dec, data, n, on_packet, NULL);
    }
    free(data);
    print_stats();
}

static void cmd_encode(char *args)
{
    char *tok[32];
    int ntok = 0;
    char *t = strtok(args, " ");
    qp_packet_t pkt;
    qp_encoder_t enc = {0, 0, 0};
    uint8_t frame[QP_MAX_FRAME];
    size_t n, i;
    while (t && ntok < 32) {
        tok[ntok++] = t;
        t = strtok(NULL, " ");
    }
    memset(&pkt, 0, sizeof pkt);
    if (ntok < 2 || !qp_text_parse(tok[1], tok + 2, ntok - 2, &pkt)) {
        printf("error\n");
        return;
    }
    enc.seq = (uint8_t)strtoul(tok[0], NULL, 0);
    n = qp_encode(&enc, &pkt, frame);
    printf("frame ");
    for (i = 0; i < n; i++)
        printf("%02x", frame[i]);
    printf("\n");
}

static void cmd_halves(char *args, int to_float)
{
    char *t = strtok(args, " ");
    printf("bits");
    while (t) {
        unsigned long v = strtoul(t, NULL, 16);
        if (to_float) {
            float f = qp_half_to_float((uint16_t)v);
            uint32_t b;
            memcpy(&b, &f, sizeof b);
            printf(" %08lx", (unsigned long)b);
        } else {
            uint32_t b = (uint32_t)v;
            float f;
            memcpy(&f, &b, sizeof f);
            printf(" %04x", qp_half_from_float(f));
        }
        t = strtok(NULL, " ");
    }
    printf("\n");
}

static void cmd_bench(char *args)
{
    char *reps = strtok(args, " "), *chunk = strtok(NULL, " "), *hex = strtok(NULL, " ");
    uint8_t *data;
    size_t n, step, i, packets = 0;
    long r, repeats;
    struct timespec t0, t1;
    if (!reps || !chunk || !hex) {
        printf("error\n");
        return;
    }
    repeats = strtol(reps, NULL, 10);
    step = (size_t)strtoul(chunk, NULL, 10);
    n = unhex(hex, &data);
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (r = 0; r < repeats; r++) {
        qp_decoder_init(&dec);
        for (i = 0; i < n; i += step)
            packets += qp_decode(&dec, data + i, n - i < step ? n - i : step, NULL, NULL);
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    free(data);
    printf("bench %.0f %lu\n", (t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec), (unsigned long)packets);
}

int main(void)
{
    char *line;
    qp_decoder_init(&dec);
    while ((line = read_line()) != NULL) {
        if (strncmp(line, "feed ", 5) == 0 || strcmp(line, "feed") == 0) {
            cmd_feed(line[4] ? line + 5 : "", 0);
        } else if (strncmp(line, "bytes ", 6) == 0) {
            cmd_feed(line + 6, 1);
        } else if (strcmp(line, "reset") == 0) {
            qp_decoder_init(&dec);
            printf("ok\n");
        } else if (strcmp(line, "resetseq") == 0) {
            qp_decoder_reset_sequence(&dec);
            printf("ok\n");
        } else if (strncmp(line, "encode ", 7) == 0) {
            cmd_encode(line + 7);
        } else if (strncmp(line, "crc ", 4) == 0) {
            uint8_t *data;
            size_t n = unhex(line + 4, &data);
            printf("crc %u\n", qp_crc16(QP_CRC_INIT, data, n));
            free(data);
        } else if (strncmp(line, "h2f ", 4) == 0) {
            cmd_halves(line + 4, 1);
        } else if (strncmp(line, "f2h ", 4) == 0) {
            cmd_halves(line + 4, 0);
        } else if (strncmp(line, "bench ", 6) == 0) {
            cmd_bench(line + 6);
        } else {
            printf("error\n");
        }
        fflush(stdout);
    }
    return 0;
}
