/*
 * hal_sim.c - HAL implementation for the simulator (see hal_sim.h).
 * The hal_flash_* functions are in hal_flash_sim.c.
 */
#include "hal_sim.h"

#include <string.h>

typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t data[8];
} sim_can_frame_t;

typedef struct {
    uint8_t buf[HAL_SIM_UART_BYTES];
    size_t head; /* next write */
    size_t tail; /* next read  */
} sim_ring_t;

typedef struct {
    sim_can_frame_t f[HAL_SIM_CAN_FRAMES];
    size_t head;
    size_t tail;
} sim_canq_t;

static struct {
    uint64_t t_ns;
    int32_t mv[HAL_MAX_AXES];
    bool enabled[HAL_MAX_AXES];
    bool amp_fault[HAL_MAX_AXES];
    bool home[HAL_MAX_AXES];
    uint32_t counter[HAL_SIM_CHANNELS];
    bool counter_valid[HAL_SIM_CHANNELS];
    hal_sim_counter_fn counter_fn[HAL_SIM_CHANNELS]; /* NULL: counter[] */
    void *counter_ctx[HAL_SIM_CHANNELS];
    hal_sim_home_fn home_fn; /* NULL: home[] */
    void *home_ctx;
    sim_ring_t to_drive, from_drive;
    sim_canq_t can_to_drive, can_from_drive;
    uint32_t kicks;
    bool reset_req;
    bool no_mean; /* hal_sim_set_mean_port(false) */
    int64_t mean_lag_q16[HAL_MAX_AXES];
} sim;

void hal_sim_reset(void)
{
    memset(&sim, 0, sizeof sim);
}

void hal_sim_set_time_ns(uint64_t t_ns)
{
    sim.t_ns = t_ns;
}

uint64_t hal_sim_time_ns(void)
{
    return sim.t_ns;
}

uint32_t hal_time_us(void)
{
    return (uint32_t)(sim.t_ns / 1000u);
}

bool hal_encoder_counter(unsigned ch, uint32_t *count)
{
    if (ch >= HAL_SIM_CHANNELS || count == NULL) {
        return false;
    }
    if (sim.counter_fn[ch] != NULL) {
        *count = sim.counter_fn[ch](sim.counter_ctx[ch], ch);
        return true;
    }
    if (!sim.counter_valid[ch]) {
        return false;
    }
    *count = sim.counter[ch];
    return true;
}

void hal_sim_set_counter(unsigned ch, uint32_t count, bool valid)
{
    if (ch < HAL_SIM_CHANNELS) {
        sim.counter[ch] = count;
        sim.counter_valid[ch] = valid;
        sim.counter_fn[ch] = NULL;
    }
}

void hal_sim_set_counter_source(unsigned ch, hal_sim_counter_fn fn, void *ctx)
{
    if (ch < HAL_SIM_CHANNELS) {
        sim.counter_fn[ch] = fn;
        sim.counter_ctx[ch] = ctx;
    }
}

bool hal_encoder_mean(unsigned axis, int64_t *lag_q16)
{
    if (sim.no_mean || axis >= HAL_MAX_AXES) {
        return false;
    }
    if (lag_q16 != NULL) {
        *lag_q16 = sim.mean_lag_q16[axis];
    }
    return true;
}

void hal_sim_set_encoder_mean(unsigned axis, int64_t lag_q16)
{
    if (axis < HAL_MAX_AXES) {
        sim.mean_lag_q16[axis] = lag_q16;
    }
}

void hal_sim_set_mean_port(bool provides)
{
    sim.no_mean = !provides;
}

void hal_motor_set_mv(unsigned axis, int32_t millivolts)
{
    if (axis >= HAL_MAX_AXES) {
        return;
    }
    if (millivolts > HAL_SIM_MV_LIMIT) {
        millivolts = HAL_SIM_MV_LIMIT;
    } else if (millivolts < -HAL_SIM_MV_LIMIT) {
        millivolts = -HAL_SIM_MV_LIMIT;
    }
    sim.mv[axis] = millivolts;
}

void hal_motor_enable(unsigned axis, bool on)
{
    if (axis < HAL_MAX_AXES) {
        sim.enabled[axis] = on;
    }
}

bool hal_amp_fault(unsigned axis)
{
    return axis < HAL_MAX_AXES && sim.amp_fault[axis];
}

void hal_motor_set_mv_all(const int32_t *mv, unsigned n)
{
    hal_generic_set_mv_all(mv, n);
}

uint32_t hal_amp_fault_mask(unsigned n)
{
    return hal_generic_amp_fault_mask(n);
}

int32_t hal_sim_motor_mv(unsigned axis)
{
    if (axis >= HAL_MAX_AXES || !sim.enabled[axis]) {
        return 0;
    }
    return sim.mv[axis];
}

bool hal_sim_motor_enabled(unsigned axis)
{
    return axis < HAL_MAX_AXES && sim.enabled[axis];
}

bool hal_home_switch(unsigned axis)
{
    if (axis >= HAL_MAX_AXES) {
        return false;
    }
    return sim.home_fn != NULL ? sim.home_fn(sim.home_ctx, axis) : sim.home[axis];
}

void hal_sim_set_home_source(hal_sim_home_fn fn, void *ctx)
{
    sim.home_fn = fn;
    sim.home_ctx = ctx;
}

void hal_sim_set_home_switch(unsigned axis, bool on)
{
    if (axis < HAL_MAX_AXES) {
        sim.home[axis] = on;
        sim.home_fn = NULL; /* as hal_sim_set_counter: the value set is read */
    }
}

void hal_sim_set_amp_fault(unsigned axis, bool fault)
{
    if (axis < HAL_MAX_AXES) {
        sim.amp_fault[axis] = fault;
    }
}

/* ---- byte rings ---------------------------------------------------------- */

static size_t ring_put(sim_ring_t *r, const uint8_t *data, size_t len)
{
    size_t n = 0;
    while (n < len) {
        size_t next = (r->head + 1u) % HAL_SIM_UART_BYTES;
        if (next == r->tail) {
            break;
        }
        r->buf[r->head] = data[n++];
        r->head = next;
    }
    return n;
}

static size_t ring_get(sim_ring_t *r, uint8_t *data, size_t cap)
{
    size_t n = 0;
    while (n < cap && r->tail != r->head) {
        data[n++] = r->buf[r->tail];
        r->tail = (r->tail + 1u) % HAL_SIM_UART_BYTES;
    }
    return n;
}

size_t hal_uart_write(const uint8_t *data, size_t len)
{
    return data == NULL ? 0 : ring_put(&sim.from_drive, data, len);
}

bool hal_uart_tx_idle(void)
{
    return sim.from_drive.tail == sim.from_drive.head;
}

size_t hal_uart_read(uint8_t *data, size_t cap)
{
    return data == NULL ? 0 : ring_get(&sim.to_drive, data, cap);
}

size_t hal_sim_uart_inject(const uint8_t *data, size_t len)
{
    return data == NULL ? 0 : ring_put(&sim.to_drive, data, len);
}

size_t hal_sim_uart_drain(uint8_t *data, size_t cap)
{
    return data == NULL ? 0 : ring_get(&sim.from_drive, data, cap);
}

/* ---- CAN frame queues ----------------------------------------------------- */

static bool canq_put(sim_canq_t *q, uint32_t id, const uint8_t *data, uint8_t len)
{
    size_t next = (q->head + 1u) % HAL_SIM_CAN_FRAMES;
    /* 11-bit ids, or 29-bit ones flagged with HAL_CAN_EFF (hal.h) */
    bool bad_id = (id & HAL_CAN_EFF) ? (id & ~HAL_CAN_EFF) > 0x1FFFFFFFu : id > 0x7FFu;

    if (len > 8 || next == q->tail || bad_id || (len > 0 && data == NULL)) {
        return false;
    }
    q->f[q->head].id = id;
    q->f[q->head].len = len;
    if (len > 0) {
        memcpy(q->f[q->head].data, data, len);
    }
    q->head = next;
    return true;
}

static bool canq_get(sim_canq_t *q, uint32_t *id, uint8_t *data, uint8_t *len)
{
    if (q->tail == q->head || id == NULL || data == NULL || len == NULL) {
        return false;
    }
    *id = q->f[q->tail].id;
    *len = q->f[q->tail].len;
    memcpy(data, q->f[q->tail].data, q->f[q->tail].len);
    q->tail = (q->tail + 1u) % HAL_SIM_CAN_FRAMES;
    return true;
}

bool hal_can_send(uint32_t id, const uint8_t *data, uint8_t len)
{
    return canq_put(&sim.can_from_drive, id, data, len);
}

bool hal_can_receive(uint32_t *id, uint8_t *data, uint8_t *len)
{
    return canq_get(&sim.can_to_drive, id, data, len);
}

bool hal_sim_can_inject(uint32_t id, const uint8_t *data, uint8_t len)
{
    return canq_put(&sim.can_to_drive, id, data, len);
}

bool hal_sim_can_drain(uint32_t *id, uint8_t *data, uint8_t *len)
{
    return canq_get(&sim.can_from_drive, id, data, len);
}

/* ---- system ----------------------------------------------------------------- */

void hal_watchdog_start(void)
{
}

void hal_watchdog_kick(void)
{
    sim.kicks++;
}

uint32_t hal_sim_watchdog_kicks(void)
{
    return sim.kicks;
}

void hal_system_reset(void)
{
    sim.reset_req = true;
}

bool hal_sim_take_reset_request(void)
{
    bool r = sim.reset_req;
    sim.reset_req = false;
    return r;
}
