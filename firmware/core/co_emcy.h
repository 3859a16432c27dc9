/*
 * co_emcy.h - CiA 301 EMCY producer of the drive's CANopen node: one
 * emergency message per drive fault (drive.h DRIVE_FAULT_*), and the error
 * register 0x1001.
 *
 * Specification
 * -------------
 * co_emcy_update(faults) (main context, every pass) compares the drive's
 * latched fault bits with those already reported. For the lowest bit that
 * differs it sends one EMCY frame on 0x1014 (default 0x080 + node; bit 31 =
 * not valid: nothing is sent, the state still follows) and marks it
 * reported; further differences wait for the next call and the inhibit
 * time 0x1015 (100 us units) since the last EMCY. A bit that appears sends
 * its error code; when the last bit clears, the code 0x0000 (error reset)
 * is sent. Frame (8 bytes): code (u16 LE), error register (0x1001), then
 * the drive's fault bits (u16 LE) and three zero bytes.
 *
 *   fault bit          code    source                 0x1001 bits
 *   following_error    0x8611  CiA 402 following error  generic, profile
 *   encoder            0x7305  CiA 402 incremental sensor 1 fault  g, p
 *   saturation         0xFF04  manufacturer (no 402 code fits)     g, mfr
 *   amplifier          0x5400  CiA 402 power section               g, current
 *   estop              0xFF10  manufacturer (emergency stop input) g, mfr
 *   comm_timeout       0x8100  CiA 301 communication (host link)   g, comm
 *                      0x8130  when the heartbeat consumer (co_hb.h) raised it
 *   homing             0xFF40  manufacturer                        g, mfr
 *   oscillation        0xFF80  manufacturer (CEC limit cycle)      g, mfr
 *
 * 0x1001 is recomputed from the reported bits: bit 0 (generic) with any,
 * bit 1 current, bit 4 communication, bit 5 device profile, bit 7
 * manufacturer. EMCY frames leave in PRE-OPERATIONAL and OPERATIONAL only
 * (not STOPPED; the state still follows). 0x1014 accepts bit 31 and an
 * 11-bit id 0x001..0x7FF (else 0x06090030).
 */
#ifndef CO_EMCY_H
#define CO_EMCY_H

#include <stdint.h>

typedef struct {
    uint32_t reported;  /* fault bits the last EMCYs described */
    uint32_t last_us;   /* time of the last EMCY */
    uint32_t sent;      /* EMCY frames sent */
    uint16_t comm_code; /* 0, or the code of the next comm_timeout (0x8130:
                         * set by co_drive on a heartbeat timeout) */
} co_emcy_t;

struct co_s;

void co_emcy_update(struct co_s *co, uint32_t faults, uint32_t now_us);
/* The EMCY error code of one DRIVE_FAULT_* bit (0x1000 generic if unknown). */
uint16_t co_emcy_code(uint32_t fault_bit);
uint32_t co_emcy_check(uint32_t value);

#endif
