/* port_boot.c - bootloader serving loop of the real-target ports (see port.h). */
#include "port.h"

#include "hal.h"
#include "proto_frame.h"
#include "proto_isotp.h"
#include "proto_msgs.h"

static struct {
    boot_t b;
    bool serial, can;
    proto_frame_rx_t rx;
    proto_isotp_t tp;
    uint8_t tx[PROTO_FRAME_MAX]; /* framed reply waiting for the UART */
    size_t tx_len, tx_pos;
    uint8_t reply[BOOT_REPLY_MAX];
} pb;

static bool can_tx(void *ctx, uint32_t id, const uint8_t *data, uint8_t len)
{
    (void)ctx;
    return hal_can_send(id, data, len);
}

bool port_boot_init(const boot_config_t *cfg, bool serial, bool can)
{
    if (cfg == NULL || !boot_init(&pb.b, cfg)) {
        return false;
    }
    pb.serial = serial;
    pb.can = can;
    pb.tx_len = pb.tx_pos = 0;
    proto_frame_rx_init(&pb.rx);
    proto_isotp_init(&pb.tp, PROTO_CAN_ID(PROTO_CAN_FUNC_REQUEST, cfg->node_id),
                     PROTO_CAN_ID(PROTO_CAN_FUNC_RESPONSE, cfg->node_id));
    (void)boot_start(&pb.b, hal_time_us());
    return true;
}

const boot_t *port_boot_state(void)
{
    return &pb.b;
}

static void uart_flush(void)
{
    while (pb.tx_pos < pb.tx_len) {
        size_t n = hal_uart_write(pb.tx + pb.tx_pos, pb.tx_len - pb.tx_pos);

        if (n == 0u) {
            return;
        }
        pb.tx_pos += n;
    }
    pb.tx_len = pb.tx_pos = 0;
}

static void serve_serial(void)
{
    uint8_t c;

    uart_flush();
    /* one request at a time: the next byte is read only once the reply is out */
    while (pb.tx_len == 0u && hal_uart_read(&c, 1u) == 1u) {
        const uint8_t *msg;
        size_t len, n;

        if (!proto_frame_rx_byte(&pb.rx, c, &msg, &len)) {
            continue;
        }
        n = boot_handle(&pb.b, msg, len, pb.reply, sizeof pb.reply);
        if (n > 0u) {
            pb.tx_len = proto_frame_encode(pb.reply, n, pb.tx, sizeof pb.tx);
            pb.tx_pos = 0;
            uart_flush();
        }
    }
}

static void serve_can(uint32_t now)
{
    uint32_t id;
    uint8_t data[8], dlc;

    while (!proto_isotp_busy(&pb.tp) && hal_can_receive(&id, data, &dlc)) {
        const uint8_t *msg;
        size_t len, n;

        if (id != pb.tp.rx_id) {
            continue;
        }
        if (dlc > 8u) {
            dlc = 8u;
        }
        if (!proto_isotp_rx(&pb.tp, data, dlc, now, &msg, &len)) {
            continue;
        }
        n = boot_handle(&pb.b, msg, len, pb.reply, sizeof pb.reply);
        if (n > 0u) {
            (void)proto_isotp_send(&pb.tp, pb.reply, n, now);
        }
    }
    proto_isotp_poll(&pb.tp, now, can_tx, NULL);
}

void port_boot_poll(void)
{
    uint32_t now = hal_time_us();

    if (pb.serial) {
        serve_serial();
    }
    if (pb.can) {
        uint8_t hb[8];

        serve_can(now);
        if (boot_heartbeat(&pb.b, now, hb)) {
            (void)hal_can_send(PROTO_CAN_ID(PROTO_CAN_FUNC_HEARTBEAT, pb.b.cfg.node_id), hb, 8u);
        }
    }
    hal_watchdog_kick();
    (void)boot_poll(&pb.b, hal_time_us());
}

void port_boot_reset(void *ctx)
{
    uint32_t t0 = hal_time_us();

    (void)ctx;
    for (;;) {
        uint32_t now = hal_time_us();

        if (pb.serial) {
            uart_flush();
        }
        if (pb.can) {
            proto_isotp_poll(&pb.tp, now, can_tx, NULL);
        }
        if ((pb.tx_len == 0u && hal_uart_tx_idle() && !proto_isotp_busy(&pb.tp)) ||
            now - t0 > PORT_RESET_DELAY_US) {
            break;
        }
    }
    hal_system_reset();
}
