/* Framing of the serial bridge protocol (docs/serial-protocol.md): CRC-32, frame encoding and a
 * stream parser that resynchronises after garbage. Portable C11, no register access, no allocation.
 *
 * Frame, little-endian: A5 5A | length u8 | version u8 | type u8 | seq u16 | payload | crc32 u32,
 * the CRC (CRC-32/ISO-HDLC, zlib's) over length..payload. Lengths are fixed per type, so a
 * corrupted length never makes the parser wait for a long frame. */
#ifndef BRIDGE_FRAME_H
#define BRIDGE_FRAME_H

#include <stddef.h>
#include <stdint.h>

#define BP_SYNC_0 0xA5u
#define BP_SYNC_1 0x5Au
#define BP_VERSION 1u
#define BP_HEADER 7u         /* sync, length, version, type, seq */
#define BP_CRC_SIZE 4u

enum bp_type {
    BP_SAMPLE = 1,           /* bridge -> host, one per tick */
    BP_COMMAND = 2,          /* host -> bridge, one per control cycle */
    BP_CONFIG = 3,           /* host -> bridge; echoed as the acknowledgement */
    BP_HEARTBEAT = 4,        /* either way when idle */
    BP_FAULT = 5,            /* bridge -> host */
};

/* Payload sizes (the Python struct formats <QIIiiiiBBH, <iiBH, <HIBBii, <BI, <BH). */
#define BP_SAMPLE_SIZE 36u
#define BP_COMMAND_SIZE 11u
#define BP_CONFIG_SIZE 16u
#define BP_HEARTBEAT_SIZE 5u
#define BP_FAULT_SIZE 3u
#define BP_MAX_PAYLOAD BP_SAMPLE_SIZE
#define BP_MAX_FRAME (BP_HEADER + BP_MAX_PAYLOAD + BP_CRC_SIZE)

/* Receive buffer: at least one whole frame, so that a full buffer always resolves into a frame or
 * skipped bytes (the parser then always makes progress). 256 B: one tick of a 2 Mbit/s UART. */
#define BP_PARSER_CAPACITY 256u

/* Payload size of a message type, or -1 for an unknown type. */
int bp_payload_size(unsigned type);

/* CRC-32/ISO-HDLC of n bytes (check value of "123456789": 0xCBF43926). */
uint32_t bp_crc32(const uint8_t *data, size_t n);

/* Write one frame into out (room for BP_HEADER + size + BP_CRC_SIZE bytes); returns its length. */
size_t bp_encode(uint8_t *out, enum bp_type type, uint16_t seq, const uint8_t *payload, size_t size);

typedef struct {
    uint8_t buf[BP_PARSER_CAPACITY];
    uint16_t start;          /* first unparsed byte */
    uint16_t end;            /* one past the last byte fed */
    uint8_t type;            /* of the frame bp_parser_next found */
    uint16_t seq;
    uint16_t offset;         /* of its payload in buf, valid until the next feed */
    uint32_t frames;         /* valid frames found */
    uint32_t crc_errors;     /* well-formed headers whose CRC failed */
    uint32_t discarded;      /* bytes skipped while searching */
} bp_parser;

void bp_parser_init(bp_parser *p);
/* Append up to n bytes; returns how many were taken (the rest after bp_parser_next has made room). */
size_t bp_parser_feed(bp_parser *p, const uint8_t *data, size_t n);
/* Advance to the next valid frame: its type, or 0 when the buffered bytes hold no complete one. */
int bp_parser_next(bp_parser *p);
const uint8_t *bp_parser_payload(const bp_parser *p);

/* Little-endian field access. */
static inline uint16_t bp_get_u16(const uint8_t *b) { return (uint16_t)(b[0] | (b[1] << 8)); }
static inline uint32_t bp_get_u32(const uint8_t *b)
{
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
}
static inline int32_t bp_get_i32(const uint8_t *b) { return (int32_t)bp_get_u32(b); }
static inline void bp_put_u16(uint8_t *b, uint16_t v) { b[0] = (uint8_t)v; b[1] = (uint8_t)(v >> 8); }
static inline void bp_put_u32(uint8_t *b, uint32_t v)
{
    b[0] = (uint8_t)v; b[1] = (uint8_t)(v >> 8); b[2] = (uint8_t)(v >> 16); b[3] = (uint8_t)(v >> 24);
}
static inline void bp_put_u64(uint8_t *b, uint64_t v)
{
    bp_put_u32(b, (uint32_t)v);
    bp_put_u32(b + 4, (uint32_t)(v >> 32));
}

#endif
