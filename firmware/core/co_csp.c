/*
 * co_csp.c - cyclic synchronous position (co_csp.h is the specification).
 */
#include "co_csp.h"

#include "fixmath.h"

void co_csp_start(co_csp_t *c, unsigned axis)
{
    drive_status_t st;
    unsigned i;

    drive_snapshot(&st);
    for (i = 0; i < CORE_AXES; i++) {
        if (c->axes == 0u || i == axis) {
            c->last[i] = st.ref[i];
        }
    }
    c->axes |= (uint8_t)(1u << axis);
    c->active = true;
}

void co_csp_stop(co_csp_t *c, unsigned axis)
{
    c->axes &= (uint8_t) ~(1u << axis);
    c->active = c->axes != 0u;
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

void co_csp_sync(co_csp_t *c, const int32_t target[CORE_AXES], int64_t period_ns)
{
    drive_block_t b = {0};
    int64_t d[3] = {0, 0, 0};
    int64_t len;
    unsigned i;

    if (!c->active || period_ns <= 0) {
        return;
    }
    b.kind = DRIVE_BLOCK_LINE;
    for (i = 0; i < CORE_AXES; i++) {
        b.target[i] = c->last[i];
        if ((c->axes & (1u << i)) != 0u) {
            b.target[i] = target[i];
            if (i < 3u) {
                d[i] = (int64_t)target[i] - c->last[i];
            }
        }
    }
    len = fx_hypot3(d[0], d[1], d[2]);
    if (len == 0) {
        return;
    }
    /* len nm in one period: len * 1e9 / period_ns nm/s (len < 2^33) */
    b.feed_nm_s = (len * 1000000000 + period_ns - 1) / period_ns;
    if (drive_queue_block(&b) != DRIVE_OK) {
        c->missed++;
        return;
    }
    for (i = 0; i < CORE_AXES; i++) {
        c->last[i] = b.target[i];
    }
    c->queued++;
}
