/* Host side of the firmware-in-the-loop build: what Python (ctypes) needs beyond bridge.h to hold
 * the core's state and look into it. Compiled only natively (with the core into one shared library);
 * the microcontroller image never contains it. */
#include "../core/bridge.h"

/* The layouts ctypes mirrors; checked at load (hardware/emulators/native_core.py). */
size_t host_sizeof_bridge(void) { return sizeof(bridge); }
size_t host_sizeof_parser(void) { return sizeof(bp_parser); }
size_t host_sizeof_caps(void) { return sizeof(bridge_caps); }
size_t host_sizeof_inputs(void) { return sizeof(bridge_inputs); }

typedef struct {
    uint8_t configured;
    uint8_t watchdog_tripped;
    uint8_t enables;
    uint8_t outputs_enabled;
    int32_t code[2];
    uint32_t commands;
    uint32_t watchdog_ticks;
    uint32_t tx_dropped;
    uint32_t frames;
    uint32_t crc_errors;
    uint32_t discarded;
    uint16_t tx_seq;
} host_bridge_view;

size_t host_sizeof_view(void) { return sizeof(host_bridge_view); }

void host_bridge_view_get(const bridge *b, host_bridge_view *v)
{
    v->configured = b->configured;
    v->watchdog_tripped = b->watchdog_tripped;
    v->enables = b->out.enables;
    v->outputs_enabled = bridge_outputs_enabled(b);
    v->code[0] = b->out.code[0];
    v->code[1] = b->out.code[1];
    v->commands = b->commands;
    v->watchdog_ticks = b->watchdog_ticks;
    v->tx_dropped = b->tx_dropped;
    v->frames = b->rx.frames;
    v->crc_errors = b->rx.crc_errors;
    v->discarded = b->rx.discarded;
    v->tx_seq = b->tx_seq;
}

/* The parser alone (the garbage property test feeds it directly). */
uint16_t host_parser_seq(const bp_parser *p) { return p->seq; }
void host_parser_counts(const bp_parser *p, uint32_t out[3])
{
    out[0] = p->frames;
    out[1] = p->crc_errors;
    out[2] = p->discarded;
}
