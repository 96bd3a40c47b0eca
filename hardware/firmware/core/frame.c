/* CRC-32, frame encoding and the resynchronising stream parser (frame.h). */
#include "frame.h"

#include <string.h>

int bp_payload_size(unsigned type)
{
    switch (type) {
    case BP_SAMPLE: return BP_SAMPLE_SIZE;
    case BP_COMMAND: return BP_COMMAND_SIZE;
    case BP_CONFIG: return BP_CONFIG_SIZE;
    case BP_HEARTBEAT: return BP_HEARTBEAT_SIZE;
    case BP_FAULT: return BP_FAULT_SIZE;
    default: return -1;
    }
}

/* Half-byte table of the reflected polynomial 0xEDB88320: 64 bytes of flash instead of 1 KiB, two
 * lookups per byte (about 12 cycles per byte on a Cortex-M4; a 47-byte frame takes ~0.6k cycles). */
static const uint32_t crc_nibble[16] = {
    0x00000000u, 0x1DB71064u, 0x3B6E20C8u, 0x26D930ACu, 0x76DC4190u, 0x6B6B51F4u, 0x4DB26158u, 0x5005713Cu,
    0xEDB88320u, 0xF00F9344u, 0xD6D6A3E8u, 0xCB61B38Cu, 0x9B64C2B0u, 0x86D3D2D4u, 0xA00AE278u, 0xBDBDF21Cu,
};

uint32_t bp_crc32(const uint8_t *data, size_t n)
{
    uint32_t crc = 0xFFFFFFFFu;
    for (size_t i = 0; i < n; i++) {
        crc ^= data[i];
        crc = (crc >> 4) ^ crc_nibble[crc & 0x0Fu];
        crc = (crc >> 4) ^ crc_nibble[crc & 0x0Fu];
    }
    return crc ^ 0xFFFFFFFFu;
}

size_t bp_encode(uint8_t *out, enum bp_type type, uint16_t seq, const uint8_t *payload, size_t size)
{
    out[0] = BP_SYNC_0;
    out[1] = BP_SYNC_1;
    out[2] = (uint8_t)size;
    out[3] = BP_VERSION;
    out[4] = (uint8_t)type;
    bp_put_u16(out + 5, seq);
    memcpy(out + BP_HEADER, payload, size);
    bp_put_u32(out + BP_HEADER + size, bp_crc32(out + 2, BP_HEADER - 2 + size));
    return BP_HEADER + size + BP_CRC_SIZE;
}

void bp_parser_init(bp_parser *p)
{
    memset(p, 0, sizeof *p);
}

size_t bp_parser_feed(bp_parser *p, const uint8_t *data, size_t n)
{
    if (p->end + n > BP_PARSER_CAPACITY && p->start > 0) {     /* make room: move the unparsed bytes down */
        size_t kept = (size_t)(p->end - p->start);
        memmove(p->buf, p->buf + p->start, kept);
        p->start = 0;
        p->end = (uint16_t)kept;
    }
    size_t room = BP_PARSER_CAPACITY - p->end;
    size_t take = n < room ? n : room;
    memcpy(p->buf + p->end, data, take);
    p->end = (uint16_t)(p->end + take);
    return take;
}

int bp_parser_next(bp_parser *p)
{
    const uint8_t *buf = p->buf;
    for (;;) {
        size_t start = p->start, end = p->end;
        if (end - start < BP_HEADER)
            return 0;
        size_t i = start;
        while (i + 1 < end && !(buf[i] == BP_SYNC_0 && buf[i + 1] == BP_SYNC_1))
            i++;
        if (i + 1 >= end) {                      /* no sync; the last byte may start one */
            size_t keep = buf[end - 1] == BP_SYNC_0 ? 1u : 0u;
            p->discarded += (uint32_t)(end - keep - start);
            p->start = (uint16_t)(end - keep);
            return 0;
        }
        if (i > start) {
            p->discarded += (uint32_t)(i - start);
            p->start = (uint16_t)i;
            start = i;
        }
        if (end - start < BP_HEADER)
            return 0;
        unsigned length = buf[start + 2];
        unsigned type = buf[start + 4];
        if (buf[start + 3] != BP_VERSION || bp_payload_size(type) != (int)length) {
            p->discarded++;
            p->start = (uint16_t)(start + 1);
            continue;
        }
        size_t crc_at = start + BP_HEADER + length;
        if (end < crc_at + BP_CRC_SIZE)
            return 0;
        if (bp_crc32(buf + start + 2, BP_HEADER - 2 + length) != bp_get_u32(buf + crc_at)) {
            p->crc_errors++;
            p->discarded++;
            p->start = (uint16_t)(start + 1);
            continue;
        }
        p->type = (uint8_t)type;
        p->seq = bp_get_u16(buf + start + 5);
        p->offset = (uint16_t)(start + BP_HEADER);
        p->start = (uint16_t)(crc_at + BP_CRC_SIZE);
        p->frames++;
        return (int)type;
    }
}

const uint8_t *bp_parser_payload(const bp_parser *p)
{
    return p->buf + p->offset;
}
