/* The bridge's protocol and safety logic (bridge.h): exactly what hardware/emulators/bridge_core.py
 * implements in Python; tests run the daemon against both. */
#include "bridge.h"

#include <string.h>

static void queue(bridge *b, enum bp_type type, const uint8_t *payload, size_t size)
{
    if (b->tx_len + BP_HEADER + size + BP_CRC_SIZE > BRIDGE_TX_CAPACITY) {
        b->tx_dropped++;
    } else {
        b->tx_len = (uint16_t)(b->tx_len + bp_encode(b->tx + b->tx_len, type, b->tx_seq, payload, size));
    }
    b->tx_seq++;            /* numbered even when lost: the host sees the gap */
}

static void go_safe(bridge *b)
{
    b->out.code[0] = b->safe_code[0];
    b->out.code[1] = b->safe_code[1];
    b->out.enables = b->caps.enable_off;
}

static int32_t clamp(int32_t v, int32_t lo, int32_t hi)
{
    return v < lo ? lo : (v > hi ? hi : v);
}

void bridge_init(bridge *b, const bridge_caps *caps)
{
    memset(b, 0, sizeof *b);
    b->caps = *caps;
    b->period_us = caps->rate_hz ? (1000000u + caps->rate_hz / 2u) / caps->rate_hz : 1000u;
    b->watchdog_ticks = 1;
    b->safe_code[0] = caps->reset_code[0];
    b->safe_code[1] = caps->reset_code[1];
    bp_parser_init(&b->rx);
    go_safe(b);
}

void bridge_restart(bridge *b)
{
    bp_parser_init(&b->rx);
    b->tx_len = 0;
    go_safe(b);
    b->since_command = 0;
    b->watchdog_tripped = b->configured;
}

bool bridge_outputs_enabled(const bridge *b)
{
    return ((b->out.enables ^ b->caps.enable_off) & (BRIDGE_OUT_ENABLE_1 | BRIDGE_OUT_ENABLE_2)) != 0;
}

void bridge_trip_watchdog(bridge *b)
{
    go_safe(b);
    b->watchdog_tripped = true;
}

static void send_sample(bridge *b)
{
    const bridge_inputs *in = &b->latched;
    uint8_t p[BP_SAMPLE_SIZE];
    uint8_t status = (uint8_t)(BRIDGE_ST_CONFIGURED | (b->watchdog_tripped ? BRIDGE_ST_WATCHDOG : 0u)
                               | (in->status & (BRIDGE_ST_ADC_STALE | BRIDGE_ST_QUADRATURE)));
    bp_put_u64(p, in->time_us - b->config_time_us);
    bp_put_u32(p + 8, in->enc[0]);
    bp_put_u32(p + 12, in->enc[1]);
    bp_put_u32(p + 16, (uint32_t)in->sg[0]);
    bp_put_u32(p + 20, (uint32_t)in->sg[1]);
    bp_put_u32(p + 24, (uint32_t)in->joint[0]);
    bp_put_u32(p + 28, (uint32_t)in->joint[1]);
    p[32] = in->inputs;
    p[33] = status;
    bp_put_u16(p + 34, b->last_command_seq);
    queue(b, BP_SAMPLE, p, sizeof p);
}

static void send_fault(bridge *b, uint8_t code, uint16_t detail)
{
    uint8_t p[BP_FAULT_SIZE] = {code, (uint8_t)detail, (uint8_t)(detail >> 8)};
    queue(b, BP_FAULT, p, sizeof p);
}

static void configure(bridge *b, const uint8_t *p)
{
    uint16_t rate_hz = bp_get_u16(p);
    uint32_t watchdog_us = bp_get_u32(p + 2);
    uint8_t counter_bits = p[6];
    uint8_t modes = p[7];
    uint8_t width = counter_bits == 16 ? BRIDGE_COUNTERS_16 : (counter_bits == 32 ? BRIDGE_COUNTERS_32 : 0u);
    const bool ok[4] = {rate_hz == b->caps.rate_hz, watchdog_us > 0 && watchdog_us <= BRIDGE_MAX_WATCHDOG_US, (width & b->caps.counter_bits) != 0,
                        modes == b->caps.modes};
    for (uint16_t i = 0; i < 4; i++) {
        if (!ok[i]) {           /* the hardware cannot do it: which field */
            send_fault(b, BRIDGE_FAULT_BAD_CONFIG, i);
            return;
        }
    }
    uint32_t ticks = (uint32_t)(((uint64_t)watchdog_us + b->period_us - 1u) / b->period_us);
    b->watchdog_ticks = ticks ? ticks : 1u;
    b->config_time_us = b->latched.time_us;
    b->safe_code[0] = clamp(bp_get_i32(p + 8), b->caps.code_min[0], b->caps.code_max[0]);
    b->safe_code[1] = clamp(bp_get_i32(p + 12), b->caps.code_min[1], b->caps.code_max[1]);
    go_safe(b);
    b->watchdog_tripped = false;
    b->since_command = 0;
    b->configured = true;
    queue(b, BP_CONFIG, p, BP_CONFIG_SIZE);    /* the acknowledgement echoes the configuration */
    send_sample(b);                            /* this tick's sample, latched already */
}

static void command(bridge *b, const uint8_t *p, uint16_t seq)
{
    b->commands++;
    b->out.code[0] = clamp(bp_get_i32(p), b->caps.code_min[0], b->caps.code_max[0]);
    b->out.code[1] = clamp(bp_get_i32(p + 4), b->caps.code_min[1], b->caps.code_max[1]);
    b->out.enables = p[8] & (BRIDGE_OUT_ENABLE_1 | BRIDGE_OUT_ENABLE_2);
    b->last_command_seq = seq;
    b->since_command = 0;
    b->watchdog_tripped = false;
}

size_t bridge_receive(bridge *b, const uint8_t *data, size_t n)
{
    return bp_parser_feed(&b->rx, data, n);
}

int bridge_poll(bridge *b)
{
    int type = bp_parser_next(&b->rx);
    const uint8_t *p = bp_parser_payload(&b->rx);
    switch (type) {
    case BP_CONFIG:
        configure(b, p);
        break;
    case BP_COMMAND:
        if (b->configured)
            command(b, p, b->rx.seq);
        break;
    case BP_HEARTBEAT: {
        uint8_t h[BP_HEARTBEAT_SIZE];
        h[0] = b->configured ? BRIDGE_STATE_RUNNING : BRIDGE_STATE_UNCONFIGURED;
        bp_put_u32(h + 1, (uint32_t)(b->latched.time_us / 1000u));
        queue(b, BP_HEARTBEAT, h, sizeof h);
        break;
    }
    default:                   /* SAMPLE and FAULT are the bridge's own; nothing else parses */
        break;
    }
    return type;
}

void bridge_tick(bridge *b)
{
    if (!b->configured)
        return;
    b->since_command++;
    if (b->since_command > b->watchdog_ticks && bridge_outputs_enabled(b))
        bridge_trip_watchdog(b);
}

void bridge_sample(bridge *b, const bridge_inputs *in)
{
    b->latched = *in;
    if (b->configured)
        send_sample(b);
}

const bridge_outputs *bridge_outputs_now(const bridge *b)
{
    return &b->out;
}

size_t bridge_take_tx(bridge *b, uint8_t *out, size_t cap)
{
    size_t n = b->tx_len < cap ? b->tx_len : cap;
    memcpy(out, b->tx, n);
    memmove(b->tx, b->tx + n, b->tx_len - n);
    b->tx_len = (uint16_t)(b->tx_len - n);
    return n;
}
