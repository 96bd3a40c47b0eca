/* The bridge on an STM32F405 (168 MHz Cortex-M4): the board layer around the portable core.
 *
 * Pin map (docs/escon-setup.md has the wiring to the ESCON 50/5s):
 *   PA15 / PB3  TIM2 CH1/CH2 (AF1)   motor 1 encoder A/B, 32-bit counter
 *   PA0  / PA1  TIM5 CH1/CH2 (AF2)   motor 2 encoder A/B, 32-bit counter
 *   PA4  / PA5  DAC1 / DAC2          ESCON 1/2 set value (through the bipolar ±10 V stage)
 *   PC0  / PC1  ADC1 IN10 / IN11     strain-gauge amplifiers 1/2 (0..3.3 V, 1.65 V = 0)
 *   PB0  / PB1  GPIO out, pull-down  ESCON 1/2 enable (high = enabled)
 *   PB4  / PB5  GPIO in, pull-up     ESCON 1/2 ready (high = ready)
 *   PA9  / PA10 USART1 TX/RX (AF7)   to the prosthesis computer, 2 Mbit/s 8N1, DMA2 streams 7/2
 *   PA13 / PA14 SWD                  flashing and debugging
 *
 * Everything runs in the 1 kHz TIM6 interrupt, in a fixed order (bridge.h): received bytes, command
 * watchdog, outputs, sensors, SAMPLE, transmit, independent-watchdog refresh. The main loop only
 * sleeps, so nothing runs concurrently with the core. If the interrupt stops (a hang, a fault
 * handler), the independent watchdog resets the MCU; every output pin is an input or hi-Z in reset,
 * and the board's pull-downs and the set-value stage's bias hold the ESCONs disabled at 0 V. */
#include <stdint.h>

#include "../../core/bridge.h"
#include "regs.h"

#ifndef HSE_HZ
#define HSE_HZ 8000000u        /* the board's crystal; make HSE_HZ=... for another one */
#endif
#define SYSCLK_HZ 168000000u
#define APB1_TIMER_HZ 84000000u
#define APB2_HZ 84000000u
#define TICK_HZ 1000u
#define BAUD 2000000u
#define RX_RING 512u           /* circular DMA buffer: 2.5 ticks at 2 Mbit/s */
#define IWDG_RELOAD 31u        /* LSI / 4 = 8 kHz nominal: 32 counts = 4 ms (2.7..7.5 ms over the LSI's 17..47 kHz) */
#define RETAINED_MAGIC 0xB41D6E13u

/* The core and the board time survive a watchdog reset (not a power cycle): .noinit is not zeroed. */
static bridge core __attribute__((section(".noinit")));
static uint64_t tick_count __attribute__((section(".noinit")));
static uint32_t retained_magic __attribute__((section(".noinit")));

static uint8_t rx_ring[RX_RING];
static uint16_t rx_read;
static uint8_t tx_buf[BRIDGE_TX_CAPACITY];
static uint16_t adc_last[2] = {2048u, 2048u};

/* Worst tick seen, in CPU cycles (read it with the debugger: `print board_worst_tick_cycles`). */
volatile uint32_t board_worst_tick_cycles;

static const bridge_caps caps = {
    .rate_hz = TICK_HZ,
    .counter_bits = BRIDGE_COUNTERS_16 | BRIDGE_COUNTERS_32,   /* 32-bit timers; 16 = their low half */
    .modes = 0,                                                /* analog set values (DAC) only */
    .enable_off = 0,                                           /* low disables: the reset state */
    .code_min = {-2048, -2048},
    .code_max = {2047, 2047},
    .reset_code = {0, 0},
};

static void pin_mode(gpio_regs *port, unsigned pin, unsigned mode, unsigned af)
{
    port->AFR[pin / 8] = (port->AFR[pin / 8] & ~(0xFu << (4 * (pin % 8)))) | (af << (4 * (pin % 8)));
    port->MODER = (port->MODER & ~(3u << (2 * pin))) | (mode << (2 * pin));
}

static void pin_pull(gpio_regs *port, unsigned pin, unsigned pull)
{
    port->PUPDR = (port->PUPDR & ~(3u << (2 * pin))) | (pull << (2 * pin));
}

/* Enables off before anything else: PB0/PB1 driven low (the external pull-downs held them so far). */
static void enables_off_first(void)
{
    RCC->AHB1ENR |= RCC_AHB1ENR_GPIOA | RCC_AHB1ENR_GPIOB | RCC_AHB1ENR_GPIOC;
    (void)RCC->AHB1ENR;
    GPIOB->BSRR = (1u << 16) | (1u << 17);
    pin_pull(GPIOB, 0, 2);
    pin_pull(GPIOB, 1, 2);
    pin_mode(GPIOB, 0, 1, 0);
    pin_mode(GPIOB, 1, 1, 0);
}

/* 168 MHz from the HSE crystal through the PLL (HSI if the crystal does not start): AHB 168,
 * APB1 42 (timers 84), APB2 84 MHz, 48 MHz for USB. */
static void clocks_init(void)
{
    uint32_t pllm = 16u, source = 0;                          /* HSI 16 MHz */
    RCC->CR |= RCC_CR_HSEON;
    for (uint32_t i = 0; i < 100000u; i++) {
        if (RCC->CR & RCC_CR_HSERDY) {
            pllm = HSE_HZ / 1000000u;
            source = RCC_PLLCFGR_SRC_HSE;
            break;
        }
    }
    /* VCO input 1 MHz, x336 = 336 MHz; /2 = 168 MHz system, /7 = 48 MHz */
    RCC->PLLCFGR = (RCC->PLLCFGR & RCC_PLLCFGR_RESERVED) | pllm | (336u << 6) | (0u << 16) | source | (7u << 24);
    RCC->CR |= RCC_CR_PLLON;
    while (!(RCC->CR & RCC_CR_PLLRDY)) {
    }
    FLASH_ACR = FLASH_ACR_LATENCY_5WS | FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN;
    RCC->CFGR = RCC_CFGR_PPRE1_DIV4 | RCC_CFGR_PPRE2_DIV2 | RCC_CFGR_SW_PLL;
    while ((RCC->CFGR & RCC_CFGR_SWS_MASK) != RCC_CFGR_SWS_PLL) {
    }
}

static void encoder_init(tim_regs *tim)
{
    tim->SMCR = TIM_SMCR_ENCODER_MODE_3;
    /* inputs TI1/TI2, filter: 8 samples at 84 MHz (95 ns) against cable noise */
    tim->CCMR1 = TIM_CCMR1_CC1S_TI1 | TIM_CCMR1_IC1F(3) | TIM_CCMR1_CC2S_TI2 | TIM_CCMR1_IC2F(3);
    tim->CCER = TIM_CCER_CC1E | TIM_CCER_CC2E;             /* rising-edge polarity on both */
    tim->ARR = 0xFFFFFFFFu;
    tim->CR1 = TIM_CR1_CEN;
}

static void peripherals_init(void)
{
    RCC->AHB1ENR |= RCC_AHB1ENR_DMA2;
    RCC->APB1ENR |= RCC_APB1ENR_TIM2 | RCC_APB1ENR_TIM5 | RCC_APB1ENR_TIM6 | RCC_APB1ENR_DAC;
    RCC->APB2ENR |= RCC_APB2ENR_USART1 | RCC_APB2ENR_ADC1;
    (void)RCC->APB2ENR;

    /* encoders */
    pin_mode(GPIOA, 15, 2, 1);
    pin_mode(GPIOB, 3, 2, 1);
    pin_mode(GPIOA, 0, 2, 2);
    pin_mode(GPIOA, 1, 2, 2);
    encoder_init(TIM2);
    encoder_init(TIM5);

    /* set values: mid-scale (0 V after the bipolar stage) loaded before the outputs are switched on */
    pin_mode(GPIOA, 4, 3, 0);
    pin_mode(GPIOA, 5, 3, 0);
    DAC->DHR12R1 = 2048u;
    DAC->DHR12R2 = 2048u;
    DAC->CR = DAC_CR_EN1 | DAC_CR_EN2;

    /* ready inputs */
    pin_pull(GPIOB, 4, 1);
    pin_pull(GPIOB, 5, 1);
    pin_mode(GPIOB, 4, 0, 0);
    pin_mode(GPIOB, 5, 0, 0);

    /* strain gauges: injected conversions of IN10, IN11, 84 + 12 cycles at 21 MHz = 4.6 us each */
    pin_mode(GPIOC, 0, 3, 0);
    pin_mode(GPIOC, 1, 3, 0);
    ADC_CCR = ADC_CCR_ADCPRE_DIV4;
    ADC1->SMPR1 = (4u << 0) | (4u << 3);
    ADC1->JSQR = (1u << 20) | (10u << 10) | (11u << 15);     /* 2 conversions: JSQ3 = 10, JSQ4 = 11 */
    ADC1->CR1 = ADC_CR1_SCAN;
    ADC1->CR2 = ADC_CR2_ADON;

    /* link: USART1 at 2 Mbit/s (84 MHz / 16 / 2.625), received bytes into a circular DMA buffer */
    pin_mode(GPIOA, 9, 2, 7);
    pin_mode(GPIOA, 10, 2, 7);
    pin_pull(GPIOA, 10, 1);
    USART1->BRR = APB2_HZ / BAUD;                             /* 42: exact */
    USART1->CR3 = USART_CR3_DMAR | USART_CR3_DMAT;
    dma_stream_regs *rx = &DMA2->S[2];
    rx->PAR = (uint32_t)&USART1->DR;
    rx->M0AR = (uint32_t)rx_ring;
    rx->NDTR = RX_RING;
    rx->CR = DMA_SCR_CHSEL(4) | DMA_SCR_MINC | DMA_SCR_CIRC | DMA_SCR_DIR_P2M | DMA_SCR_EN;
    DMA2->S[7].PAR = (uint32_t)&USART1->DR;
    USART1->CR1 = USART_CR1_UE | USART_CR1_TE | USART_CR1_RE;

    /* cycle counter for the tick's own timing */
    DEMCR |= DEMCR_TRCENA;
    DWT_CYCCNT = 0;
    DWT_CTRL |= DWT_CTRL_CYCCNTENA;
}

static void watchdog_start(void)
{
    IWDG->KR = IWDG_KEY_START;        /* starts the LSI too; cannot be stopped until reset */
    IWDG->KR = IWDG_KEY_UNLOCK;
    IWDG->PR = 0;                     /* LSI / 4 */
    IWDG->RLR = IWDG_RELOAD;
    IWDG->KR = IWDG_KEY_REFRESH;
}

static void tick_start(void)
{
    TIM6->PSC = APB1_TIMER_HZ / 1000000u - 1u;   /* 1 MHz */
    TIM6->ARR = 1000000u / TICK_HZ - 1u;
    TIM6->EGR = TIM_EGR_UG;
    TIM6->SR = 0;
    TIM6->DIER = TIM_DIER_UIE;
    ADC1->CR2 |= ADC_CR2_JSWSTART;               /* the first tick's strain gauges */
    NVIC_IPR8[IRQ_TIM6_DAC] = 0x10;              /* high priority; nothing else is enabled */
    NVIC_ISER[IRQ_TIM6_DAC / 32] = 1u << (IRQ_TIM6_DAC % 32);
    TIM6->CR1 = TIM_CR1_CEN;
}

static void receive(void)
{
    uint16_t write = (uint16_t)(RX_RING - DMA2->S[2].NDTR);
    while (rx_read != write) {
        uint16_t end = write > rx_read ? write : (uint16_t)RX_RING;
        size_t taken = bridge_receive(&core, rx_ring + rx_read, (size_t)(end - rx_read));
        rx_read = (uint16_t)((rx_read + taken) % RX_RING);
        bool acted = false;
        while (bridge_poll(&core))
            acted = true;
        if (!taken && !acted)       /* cannot happen (the parser holds a whole frame); never spin */
            break;
    }
}

static void write_outputs(void)
{
    const bridge_outputs *out = bridge_outputs_now(&core);
    DAC->DHR12R1 = (uint32_t)(out->code[0] + 2048);      /* two's complement to offset binary */
    DAC->DHR12R2 = (uint32_t)(out->code[1] + 2048);
    uint32_t set = (out->enables & BRIDGE_OUT_ENABLE_1 ? 1u : 1u << 16) | (out->enables & BRIDGE_OUT_ENABLE_2 ? 2u : 2u << 16);
    GPIOB->BSRR = set;
}

static void latch(bridge_inputs *in)
{
    in->time_us = tick_count * (1000000u / TICK_HZ);
    in->enc[0] = TIM2->CNT;
    in->enc[1] = TIM5->CNT;
    in->status = 0;
    if (ADC1->SR & ADC_SR_JEOC) {                 /* started at the end of the last tick */
        adc_last[0] = (uint16_t)ADC1->JDR[0];
        adc_last[1] = (uint16_t)ADC1->JDR[1];
        ADC1->SR = ~ADC_SR_JEOC;
    } else {
        in->status |= BRIDGE_ST_ADC_STALE;
    }
    /* 12-bit, 1.65 V = 0, scaled to the 24-bit range of config/hw-serial.yaml */
    in->sg[0] = ((int32_t)adc_last[0] - 2048) * 4096;
    in->sg[1] = ((int32_t)adc_last[1] - 2048) * 4096;
    in->joint[0] = in->joint[1] = 0;             /* no joint encoders on this board */
    uint32_t idr = GPIOB->IDR;
    in->inputs = (uint8_t)((idr & (1u << 4) ? BRIDGE_IN_READY_1 : 0u) | (idr & (1u << 5) ? BRIDGE_IN_READY_2 : 0u));
}

static void transmit(void)
{
    dma_stream_regs *tx = &DMA2->S[7];
    if (tx->CR & DMA_SCR_EN)                     /* still sending: the frames wait in the core */
        return;
    size_t n = bridge_take_tx(&core, tx_buf, sizeof tx_buf);
    if (!n)
        return;
    DMA2->HIFCR = DMA_HIFCR_STREAM7_ALL;
    tx->M0AR = (uint32_t)tx_buf;
    tx->NDTR = (uint32_t)n;
    tx->CR = DMA_SCR_CHSEL(4) | DMA_SCR_MINC | DMA_SCR_DIR_M2P | DMA_SCR_EN;
}

void TIM6_DAC_IRQHandler(void)
{
    uint32_t start = DWT_CYCCNT;
    TIM6->SR = 0;
    tick_count++;
    receive();
    bridge_tick(&core);
    write_outputs();
    bridge_inputs in;
    latch(&in);
    ADC1->CR2 |= ADC_CR2_JSWSTART;               /* the next tick's strain gauges */
    bridge_sample(&core, &in);
    transmit();
    IWDG->KR = IWDG_KEY_REFRESH;
    uint32_t took = DWT_CYCCNT - start;
    if (took > board_worst_tick_cycles)
        board_worst_tick_cycles = took;
}

/* Any fault: outputs safe at once, then wait for the independent watchdog's reset. */
void board_fault(void)
{
    GPIOB->BSRR = (1u << 16) | (1u << 17);
    DAC->DHR12R1 = 2048u;
    DAC->DHR12R2 = 2048u;
    for (;;) {
    }
}

int main(void)
{
    enables_off_first();
    bool watchdog_reset = (RCC->CSR & RCC_CSR_IWDGRSTF) != 0;
    RCC->CSR |= RCC_CSR_RMVF;
    clocks_init();
    peripherals_init();
    if (watchdog_reset && retained_magic == RETAINED_MAGIC && core.configured
            && core.caps.rate_hz == caps.rate_hz && core.caps.counter_bits == caps.counter_bits) {
        bridge_restart(&core);                   /* configured before the hang: go on, safe, flagged */
        tick_count += (IWDG_RELOAD + 1u) * TICK_HZ / 8000u;
    } else {
        bridge_init(&core, &caps);
        tick_count = 0;
        retained_magic = RETAINED_MAGIC;
    }
    watchdog_start();
    tick_start();
    for (;;)
        __asm volatile("wfi");
}
