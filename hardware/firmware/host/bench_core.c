/* Native timing of the core's tick (benchmarks/bench_firmware.py builds and runs it): per tick the
 * board's work without registers: one COMMAND received and acted on, the watchdog, one SAMPLE built
 * and taken for transmission. Then the worst case the link can deliver: a whole tick of received
 * bytes (200 at 2 Mbit/s) made of frame headers that pass every check but the CRC, one every 5
 * bytes, so that the parser runs the CRC as often as the bytes allow. Prints ns per tick. */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../core/bridge.h"

#ifdef __arm__
/* Cross-compiled for the Cortex-M4 and run in QEMU with -icount shift=0 (one instruction per virtual
 * ns): the SysTick on the 168 MHz processor clock counts 0.168 per instruction; "ns" here are
 * virtual ns, i.e. instructions. At most 0.1 s (2^24 counts) per run. */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
static double now_ns(void)
{
    if (!(SYST_CSR & 1u)) {
        SYST_RVR = 0xFFFFFFu;
        SYST_CVR = 0;
        SYST_CSR = 5u;                 /* enabled, processor clock, no interrupt */
        while (SYST_CVR == 0) {        /* until it has loaded the reload value */
        }
    }
    return (double)(0xFFFFFFu - SYST_CVR) / 0.168;
}
#else
static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}
#endif

static size_t command(uint8_t *out, uint16_t seq, int32_t c1, int32_t c2)
{
    uint8_t p[BP_COMMAND_SIZE];
    bp_put_u32(p, (uint32_t)c1);
    bp_put_u32(p + 4, (uint32_t)c2);
    p[8] = 3;
    bp_put_u16(p + 9, seq);
    return bp_encode(out, BP_COMMAND, seq, p, sizeof p);
}

static double run(bridge *b, const uint8_t *rx, size_t rx_len, int ticks, int vary)
{
    bridge_inputs in = {0};
    uint8_t out[BRIDGE_TX_CAPACITY];
    uint8_t frame[BP_MAX_FRAME];
    uint32_t sink = 0;
    double t0 = now_ns();
    for (int k = 0; k < ticks; k++) {
        const uint8_t *data = rx;
        size_t n = rx_len;
        if (vary) {
            n = command(frame, (uint16_t)k, k % 4000 - 2000, 2000 - k % 4000);
            data = frame;
        }
        while (n) {
            size_t taken = bridge_receive(b, data, n);
            data += taken;
            n -= taken;
            while (bridge_poll(b)) {
            }
        }
        bridge_tick(b);
        in.time_us += 1000;
        in.enc[0] += 3;
        in.enc[1] -= 2;
        in.sg[0] = k;
        bridge_sample(b, &in);
        sink += (uint32_t)bridge_take_tx(b, out, sizeof out);
    }
    double ns = (now_ns() - t0) / ticks;
    if (sink == 0)
        fprintf(stderr, "nothing sent\n");
    return ns;
}

int main(int argc, char **argv)
{
    int ticks = argc > 1 ? atoi(argv[1]) : 200000;
    bridge_caps caps = {.rate_hz = 1000, .counter_bits = BRIDGE_COUNTERS_16 | BRIDGE_COUNTERS_32,
                        .code_min = {-2048, -2048}, .code_max = {2047, 2047}};
    static bridge b;
    bridge_init(&b, &caps);
    uint8_t cfg[BP_CONFIG_SIZE] = {0xE8, 0x03, 0x88, 0x13, 0, 0, 16, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    uint8_t frame[BP_MAX_FRAME];
    size_t n = bp_encode(frame, BP_CONFIG, 0, cfg, sizeof cfg);
    bridge_receive(&b, frame, n);
    while (bridge_poll(&b)) {
    }
    printf("normal %.1f\n", run(&b, NULL, 0, ticks, 1));
    /* worst case: A5 5A 24 01 01 repeated: SAMPLE headers (length 36), none with a valid CRC */
    uint8_t garbage[200];
    for (size_t i = 0; i < sizeof garbage; i++)
        garbage[i] = (const uint8_t[]){0xA5, 0x5A, 36, 1, 1}[i % 5];
    printf("worst %.1f\n", run(&b, garbage, sizeof garbage, ticks / 10, 0));
    return 0;
}
