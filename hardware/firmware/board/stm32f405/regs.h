/* The few STM32F405 registers the board layer uses, from RM0090 (STM32F405/415 reference manual,
 * rev. 19) and PM0214 (Cortex-M4 programming manual). ST's CMSIS device headers are not in Debian,
 * and the bridge needs only these: each block is a struct laid out as the manual's register map
 * (offsets in the comments), each bit a named mask next to the register it belongs to. */
#ifndef BOARD_REGS_H
#define BOARD_REGS_H

#include <stdint.h>

#define REG volatile uint32_t

/* RCC, 0x4002 3800 (RM0090 6.3) */
typedef struct {
    REG CR;         /* 0x00 */
    REG PLLCFGR;    /* 0x04 */
    REG CFGR;       /* 0x08 */
    REG CIR;        /* 0x0C */
    REG AHB1RSTR, AHB2RSTR, AHB3RSTR, RESERVED0;        /* 0x10..0x1C */
    REG APB1RSTR, APB2RSTR, RESERVED1[2];               /* 0x20..0x2C */
    REG AHB1ENR, AHB2ENR, AHB3ENR, RESERVED2;           /* 0x30..0x3C */
    REG APB1ENR, APB2ENR, RESERVED3[2];                 /* 0x40..0x4C */
    REG AHB1LPENR, AHB2LPENR, AHB3LPENR, RESERVED4;     /* 0x50..0x5C */
    REG APB1LPENR, APB2LPENR, RESERVED5[2];             /* 0x60..0x6C */
    REG BDCR;       /* 0x70 */
    REG CSR;        /* 0x74 */
} rcc_regs;
#define RCC ((rcc_regs *)0x40023800u)
#define RCC_CR_HSEON (1u << 16)
#define RCC_CR_HSERDY (1u << 17)
#define RCC_CR_PLLON (1u << 24)
#define RCC_CR_PLLRDY (1u << 25)
#define RCC_PLLCFGR_SRC_HSE (1u << 22)
#define RCC_PLLCFGR_RESERVED 0xF0BC8000u      /* bits to keep at their reset value */
#define RCC_CFGR_SW_PLL 2u
#define RCC_CFGR_SWS_MASK (3u << 2)
#define RCC_CFGR_SWS_PLL (2u << 2)
#define RCC_CFGR_PPRE1_DIV4 (5u << 10)
#define RCC_CFGR_PPRE2_DIV2 (4u << 13)
#define RCC_AHB1ENR_GPIOA (1u << 0)
#define RCC_AHB1ENR_GPIOB (1u << 1)
#define RCC_AHB1ENR_GPIOC (1u << 2)
#define RCC_AHB1ENR_DMA2 (1u << 22)
#define RCC_APB1ENR_TIM2 (1u << 0)
#define RCC_APB1ENR_TIM5 (1u << 3)
#define RCC_APB1ENR_TIM6 (1u << 4)
#define RCC_APB1ENR_DAC (1u << 29)
#define RCC_APB2ENR_USART1 (1u << 4)
#define RCC_APB2ENR_ADC1 (1u << 8)
#define RCC_CSR_RMVF (1u << 24)
#define RCC_CSR_IWDGRSTF (1u << 29)

/* Flash interface, 0x4002 3C00 (RM0090 3.9) */
#define FLASH_ACR (*(REG *)0x40023C00u)
#define FLASH_ACR_LATENCY_5WS 5u       /* 168 MHz at 2.7-3.6 V */
#define FLASH_ACR_PRFTEN (1u << 8)
#define FLASH_ACR_ICEN (1u << 9)
#define FLASH_ACR_DCEN (1u << 10)

/* GPIO, port A 0x4002 0000, B 0x4002 0400, C 0x4002 0800 (RM0090 8.4) */
typedef struct {
    REG MODER;      /* 0x00: 2 bits per pin, 00 input, 01 output, 10 alternate function, 11 analog */
    REG OTYPER;     /* 0x04 */
    REG OSPEEDR;    /* 0x08 */
    REG PUPDR;      /* 0x0C: 01 pull-up, 10 pull-down */
    REG IDR;        /* 0x10 */
    REG ODR;        /* 0x14 */
    REG BSRR;       /* 0x18: bit n sets pin n, bit n+16 resets it */
    REG LCKR;       /* 0x1C */
    REG AFR[2];     /* 0x20, 0x24: 4 bits per pin */
} gpio_regs;
#define GPIOA ((gpio_regs *)0x40020000u)
#define GPIOB ((gpio_regs *)0x40020400u)
#define GPIOC ((gpio_regs *)0x40020800u)

/* General-purpose timers TIM2 0x4000 0000, TIM5 0x4000 0C00 (32-bit); basic TIM6 0x4000 1000 (RM0090 18, 20) */
typedef struct {
    REG CR1;        /* 0x00 */
    REG CR2;        /* 0x04 */
    REG SMCR;       /* 0x08 */
    REG DIER;       /* 0x0C */
    REG SR;         /* 0x10 */
    REG EGR;        /* 0x14 */
    REG CCMR1;      /* 0x18 */
    REG CCMR2;      /* 0x1C */
    REG CCER;       /* 0x20 */
    REG CNT;        /* 0x24 */
    REG PSC;        /* 0x28 */
    REG ARR;        /* 0x2C */
} tim_regs;
#define TIM2 ((tim_regs *)0x40000000u)
#define TIM5 ((tim_regs *)0x40000C00u)
#define TIM6 ((tim_regs *)0x40001000u)
#define TIM_CR1_CEN (1u << 0)
#define TIM_DIER_UIE (1u << 0)
#define TIM_SR_UIF (1u << 0)
#define TIM_EGR_UG (1u << 0)
#define TIM_SMCR_ENCODER_MODE_3 3u             /* count on both edges of both inputs */
#define TIM_CCER_CC1E (1u << 0)
#define TIM_CCER_CC2E (1u << 4)
#define TIM_CCMR1_CC1S_TI1 (1u << 0)
#define TIM_CCMR1_CC2S_TI2 (1u << 8)
#define TIM_CCMR1_IC1F(n) ((uint32_t)(n) << 4)
#define TIM_CCMR1_IC2F(n) ((uint32_t)(n) << 12)

/* DAC, 0x4000 7400 (RM0090 14.5) */
typedef struct {
    REG CR;         /* 0x00 */
    REG SWTRIGR;    /* 0x04 */
    REG DHR12R1;    /* 0x08 */
    REG DHR12L1, DHR8R1;        /* 0x0C, 0x10 */
    REG DHR12R2;    /* 0x14 */
} dac_regs;
#define DAC ((dac_regs *)0x40007400u)
#define DAC_CR_EN1 (1u << 0)
#define DAC_CR_EN2 (1u << 16)

/* ADC1, 0x4001 2000; common registers 0x4001 2300 (RM0090 13.13) */
typedef struct {
    REG SR;         /* 0x00 */
    REG CR1;        /* 0x04 */
    REG CR2;        /* 0x08 */
    REG SMPR1;      /* 0x0C: channels 10..18 */
    REG SMPR2;      /* 0x10 */
    REG JOFR[4];    /* 0x14..0x20 */
    REG HTR, LTR;   /* 0x24, 0x28 */
    REG SQR1, SQR2, SQR3;       /* 0x2C..0x34 */
    REG JSQR;       /* 0x38 */
    REG JDR[4];     /* 0x3C..0x48 */
    REG DR;         /* 0x4C */
} adc_regs;
#define ADC1 ((adc_regs *)0x40012000u)
#define ADC_CCR (*(REG *)0x40012304u)
#define ADC_CCR_ADCPRE_DIV4 (1u << 16)
#define ADC_SR_JEOC (1u << 2)
#define ADC_CR1_SCAN (1u << 8)
#define ADC_CR2_ADON (1u << 0)
#define ADC_CR2_JSWSTART (1u << 22)

/* USART1, 0x4001 1000 (RM0090 30.6) */
typedef struct {
    REG SR;         /* 0x00 */
    REG DR;         /* 0x04 */
    REG BRR;        /* 0x08 */
    REG CR1;        /* 0x0C */
    REG CR2;        /* 0x10 */
    REG CR3;        /* 0x14 */
} usart_regs;
#define USART1 ((usart_regs *)0x40011000u)
#define USART_CR1_RE (1u << 2)
#define USART_CR1_TE (1u << 3)
#define USART_CR1_UE (1u << 13)
#define USART_CR3_DMAR (1u << 6)
#define USART_CR3_DMAT (1u << 7)

/* DMA2, 0x4002 6400 (RM0090 10.5); USART1 RX = stream 2 channel 4, TX = stream 7 channel 4 (table 43) */
typedef struct {
    REG CR;         /* +0x00 */
    REG NDTR;       /* +0x04 */
    REG PAR;        /* +0x08 */
    REG M0AR;       /* +0x0C */
    REG M1AR;       /* +0x10 */
    REG FCR;        /* +0x14 */
} dma_stream_regs;
typedef struct {
    REG LISR, HISR, LIFCR, HIFCR;   /* 0x00..0x0C */
    dma_stream_regs S[8];           /* 0x10 + 0x18 * n */
} dma_regs;
#define DMA2 ((dma_regs *)0x40026400u)
#define DMA_SCR_EN (1u << 0)
#define DMA_SCR_DIR_P2M (0u << 6)
#define DMA_SCR_DIR_M2P (1u << 6)
#define DMA_SCR_CIRC (1u << 8)
#define DMA_SCR_MINC (1u << 10)
#define DMA_SCR_CHSEL(n) ((uint32_t)(n) << 25)
#define DMA_HIFCR_STREAM7_ALL (0x3Du << 22)   /* TCIF7, HTIF7, TEIF7, DMEIF7, FEIF7 */

/* Independent watchdog, 0x4000 3000 (RM0090 21.4), clocked by the ~32 kHz LSI */
typedef struct {
    REG KR;         /* 0x00 */
    REG PR;         /* 0x04 */
    REG RLR;        /* 0x08 */
    REG SR;         /* 0x0C */
} iwdg_regs;
#define IWDG ((iwdg_regs *)0x40003000u)
#define IWDG_KEY_UNLOCK 0x5555u
#define IWDG_KEY_REFRESH 0xAAAAu
#define IWDG_KEY_START 0xCCCCu

/* Cortex-M4 system (PM0214 4.2-4.4; DWT in the ARMv7-M architecture manual C1.8) */
#define NVIC_ISER ((REG *)0xE000E100u)
#define NVIC_IPR8 ((volatile uint8_t *)0xE000E400u)
#define SCB_VTOR (*(REG *)0xE000ED08u)
#define DEMCR (*(REG *)0xE000EDFCu)
#define DEMCR_TRCENA (1u << 24)
#define DWT_CTRL (*(REG *)0xE0001000u)
#define DWT_CYCCNT (*(REG *)0xE0001004u)
#define DWT_CTRL_CYCCNTENA 1u

#define IRQ_TIM6_DAC 54u

#endif
