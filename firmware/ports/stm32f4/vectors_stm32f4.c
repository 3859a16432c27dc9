/* vectors_stm32f4.c - vector table of both STM32F4 images (16 + 82 entries). */
#include <stdint.h>

#include "stm32f4.h"

extern uint32_t _estack;
void cm4_reset_handler(void);
void cm4_default_handler(void);
void f4_systick_handler(void);
void f4_usart2_handler(void);
void f4_can1_rx0_handler(void);

typedef void (*vector_t)(void);

__attribute__((section(".isr_vector"), used)) const vector_t f4_vectors[16 + F4_IRQS] = {
    [0] = (vector_t)(uintptr_t)&_estack,
    [1] = cm4_reset_handler,
    [2] = cm4_default_handler, /* NMI */
    [3] = cm4_default_handler, /* HardFault */
    [4] = cm4_default_handler,
    [5] = cm4_default_handler,
    [6] = cm4_default_handler,
    [11] = cm4_default_handler,
    [14] = cm4_default_handler,
    [15] = f4_systick_handler,
    [16 + F4_IRQ_CAN1_RX0] = f4_can1_rx0_handler,
    [16 + F4_IRQ_USART2] = f4_usart2_handler,
};
