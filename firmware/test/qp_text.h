/* qp_text.h: packets as text lines and back, for the C test runner (host only). The code is generated from the
 * packet table (qp_text.c, by firmware/gen_c.py); tests/firmware/test_firmware.py reads what it prints. */
#ifndef QP_TEXT_H
#define QP_TEXT_H

#include <stdio.h>

#include "qp_protocol.h"

/* The packet type's name as in term/core/protocol/, or NULL for an unknown type. */
const char *qp_text_name(uint8_t type);

/* ``Name field=value ...``: integers in decimal, half floats as their raw bits, byte strings in hex. */
void qp_text_print(FILE *f, const qp_packet_t *pkt);

/* A packet from its type name and one token per field (the same notation); returns 0 if they do not fit. */
int qp_text_parse(const char *name, char **tok, int ntok, qp_packet_t *pkt);

#endif /* QP_TEXT_H */
