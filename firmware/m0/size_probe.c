/* size_probe.c: what a board links of the codec, for the Cortex-M0 size figure (bench/firmware.py).
 *
 * A board decodes the terminal's packets (slices and single bytes), checks the Hello and encodes its packets
 * (through qp_encode, which links every encoder: an upper bound). It does not need the half-float helpers.
 * Linked with --gc-sections from probe_main, so `size` counts that and nothing else: the codec's flash (text +
 * rodata, memset included) and its RAM (the decoder, encoder and frame buffer below). */
#include "qp_protocol.h"

void probe_main(void);

static qp_decoder_t dec;
static qp_encoder_t enc;
static uint8_t frame[QP_MAX_FRAME];
static qp_packet_t pkt;
static volatile uint32_t sink;

static void on_packet(void *ctx, const qp_packet_t *p)
{
    (void)ctx;
    sink += p->type;
}

void probe_main(void)
{
    static const uint8_t rx[] = {0x02, 0x04, 0x03, 0x01, 0x01, 0x02, 0x01, 0x01, 0x03, 0x35, 0x64, 0x00};
    size_t n = qp_decode(&dec, rx, sizeof rx, on_packet, 0);
    if (qp_decode_byte(&dec, 0, &pkt) && qp_hello_compatible(&pkt.u.hello))
        n++;
    n += qp_encode(&enc, &pkt, frame);  /* any packet: every encoder is linked (the PC's three too) */
    sink += (uint32_t)n;
    for (;;) {
    }
}
