/*
 * co_csp.c - cyclic synchronous position (co_csp.h is the specification).
 */
#include "co_csp.h"

void co_csp_start(co_csp_t *c)
{
    drive_status_t st;
    unsigned i;

    drive_snapshot(&st);
    for (i = 0; i < CORE_AXES; i++) {
        c->last[i] = st.ref[i];
    }
    c->active = true;
}

void co_csp_stop(co_csp_t *c)
{
    c->active = false;
}

int64_t co_csp_period_ns(uint8_t value, int8_t index)
{
    int64_t ns = value;
    int k;

    if (index < -6 || index > -3) {
        return 0;
    }
    for (k = 9 + index; k > 0; k--) {
        ns *= 10;
    }
    return ns;
}

void co_csp_sync(co_csp_t *c, int32_t target, int64_t period_ns)
{
    drive_block_t b = {0};
    int64_t d = (int64_t)target - c->last[0];
    unsigned i;

    if (!c->active || d == 0 || period_ns <= 0) {
        return;
    }
    b.kind = DRIVE_BLOCK_LINE;
    for (i = 0; i < CORE_AXES; i++) {
        b.target[i] = c->last[i];
    }
    b.target[0] = target;
    /* |d| nm in one period: |d| * 1e9 / period_ns nm/s (|d| < 2^32: no overflow) */
    b.feed_nm_s = ((d < 0 ? -d : d) * 1000000000 + period_ns - 1) / period_ns;
    if (drive_queue_block(&b) != DRIVE_OK) {
        c->missed++;
        return;
    }
    c->last[0] = target;
    c->queued++;
}
