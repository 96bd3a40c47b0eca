/* The bridge firmware's portable core: the protocol and safety logic of docs/serial-protocol.md,
 * with no register access, so that the same code runs on the microcontroller (board/) and, compiled
 * natively, in the firmware-in-the-loop emulator (hardware/emulators/native_core.py).
 *
 * The board calls, each tick of its 1 kHz timer:
 *   1. bridge_receive() with the bytes its UART received, then bridge_poll() until it returns 0
 *      (COMMAND frames update the outputs, CONFIG reconfigures, HEARTBEAT is answered);
 *   2. bridge_tick(): the command watchdog (no valid command for watchdog_us while an enable is on:
 *      safe codes, enables off, status bit 0 until the next valid command);
 *   3. writes bridge_outputs() to its DAC/PWM and enable lines, latches its sensors;
 *   4. bridge_sample() with the latched sensors: queues the SAMPLE frame (once configured);
 *   5. sends what bridge_take_tx() hands out.
 * Nothing blocks or allocates; every entry point is safe on any input bytes. */
#ifndef BRIDGE_CORE_H
#define BRIDGE_CORE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "frame.h"

/* SAMPLE.inputs bits */
#define BRIDGE_IN_READY_1 0x01u
#define BRIDGE_IN_READY_2 0x02u
#define BRIDGE_IN_JOINT_VALID 0x04u
/* SAMPLE.status bits */
#define BRIDGE_ST_WATCHDOG 0x01u
#define BRIDGE_ST_ADC_STALE 0x02u
#define BRIDGE_ST_QUADRATURE 0x04u
#define BRIDGE_ST_CONFIGURED 0x80u
/* COMMAND.outputs bits: enable line levels */
#define BRIDGE_OUT_ENABLE_1 0x01u
#define BRIDGE_OUT_ENABLE_2 0x02u
/* FAULT codes */
#define BRIDGE_FAULT_BAD_CONFIG 1u
#define BRIDGE_MAX_WATCHDOG_US 1000000u   /* longer: outputs on long after the host is gone (hardware/serial_protocol.py) */
#define BRIDGE_FAULT_INTERNAL 2u
/* HEARTBEAT.state */
#define BRIDGE_STATE_UNCONFIGURED 0u
#define BRIDGE_STATE_RUNNING 2u
/* bridge_caps.counter_bits */
#define BRIDGE_COUNTERS_16 0x01u
#define BRIDGE_COUNTERS_32 0x02u

#define BRIDGE_TX_CAPACITY 256u    /* frames waiting for the UART; a full buffer drops the new frame */

/* What the board's hardware can do and how it is wired: a CONFIG asking for anything else is
 * refused with FAULT(1, index of the field). */
typedef struct {
    uint16_t rate_hz;          /* the tick rate of the board's timer */
    uint8_t counter_bits;      /* BRIDGE_COUNTERS_16 | BRIDGE_COUNTERS_32: counter widths it can report */
    uint8_t modes;             /* set-value modes wired (CONFIG.modes bit 0/1: PWM on ESCON 1/2) */
    uint8_t enable_off;        /* enable line levels (bit 0/1) that disable ESCON 1/2 */
    int32_t code_min[2];       /* set-value code range of each output; commands are clamped to it */
    int32_t code_max[2];
    int32_t reset_code[2];     /* the codes the outputs hold from reset until the first CONFIG */
} bridge_caps;

/* The sensors latched at one tick. */
typedef struct {
    uint64_t time_us;          /* board time of the latch (the core subtracts the CONFIG's) */
    uint32_t enc[2];           /* motor counters, raw */
    int32_t sg[2];             /* strain-gauge ADCs, signed counts */
    int32_t joint[2];          /* joint encoders (valid if inputs bit 2) */
    uint8_t inputs;            /* ready lines, joint-encoder presence (SAMPLE.inputs) */
    uint8_t status;            /* board flags: BRIDGE_ST_ADC_STALE, BRIDGE_ST_QUADRATURE */
} bridge_inputs;

/* What the outputs are to be now (electrical levels). */
typedef struct {
    int32_t code[2];
    uint8_t enables;           /* enable line levels, bit 0/1 */
} bridge_outputs;

typedef struct {
    bridge_caps caps;
    bp_parser rx;
    uint8_t tx[BRIDGE_TX_CAPACITY];
    uint16_t tx_len;
    uint16_t tx_seq;           /* numbers every frame sent */
    bool configured;
    bool watchdog_tripped;
    uint32_t period_us;
    uint32_t watchdog_ticks;   /* ceil(CONFIG.watchdog_us / period), at least 1 */
    uint32_t since_command;    /* ticks since the last valid command */
    uint64_t config_time_us;   /* board time at the CONFIG: SAMPLE.time_us counts from it */
    int32_t safe_code[2];
    bridge_outputs out;
    uint16_t last_command_seq;
    bridge_inputs latched;
    uint32_t commands;         /* valid commands applied */
    uint32_t tx_dropped;       /* frames the full TX buffer could not take */
} bridge;

void bridge_init(bridge *b, const bridge_caps *caps);
/* After a reset of the hardware watchdog with the core's state retained: buffers cleared, outputs
 * safe, and (if configured) the watchdog status bit set so that the host learns of it. */
void bridge_restart(bridge *b);
/* Take up to n received bytes (the rest after bridge_poll has made room); returns how many. */
size_t bridge_receive(bridge *b, const uint8_t *data, size_t n);
/* Act on the next complete frame: its type, or 0 when none is buffered. */
int bridge_poll(bridge *b);
/* The command watchdog, once per tick before the outputs are written. */
void bridge_tick(bridge *b);
/* Latch this tick's sensors and, once configured, queue the SAMPLE frame. */
void bridge_sample(bridge *b, const bridge_inputs *in);
/* Safe codes, enables off, status bit 0 until the next valid command. */
void bridge_trip_watchdog(bridge *b);
bool bridge_outputs_enabled(const bridge *b);
const bridge_outputs *bridge_outputs_now(const bridge *b);
/* Move up to cap bytes of queued frames into out; returns how many. */
size_t bridge_take_tx(bridge *b, uint8_t *out, size_t cap);

#endif
