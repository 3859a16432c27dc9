/* vectors_mps2.c - vector table of both mps2-an386 images (16 + 32 entries). */
#include <stdint.h>

#include "mps2.h"

extern uint32_t _estack;
void cm4_reset_handler(void);
void cm4_default_handler(void);
void mps2_systick_handler(void);
void mps2_uart0_rx_handler(void);
void mps2_uart0_tx_handler(void);

typedef void (*vector_t)(void);

__attribute__((section(".isr_vector"), used)) const vector_t mps2_vectors[16 + MPS2_IRQS] = {
    [0] = (vector_t)(uintptr_t)&_estack,
    [1] = cm4_reset_handler,
    [2] = cm4_default_handler, /* NMI (watchdog) */
    [3] = cm4_default_handler, /* HardFault */
    [4] = cm4_default_handler,
    [5] = cm4_default_handler,
    [6] = cm4_default_handler,
    [11] = cm4_default_handler, /* SVCall */
    [14] = cm4_default_handler, /* PendSV */
    [15] = mps2_systick_handler,
    [16 + MPS2_IRQ_UART0_RX] = mps2_uart0_rx_handler,
    [16 + MPS2_IRQ_UART0_TX] = mps2_uart0_tx_handler,
};
