/* port_app.c - application background loop of the real-target ports (see port.h). */
#include "port.h"

#include "calib.h"
#include "drive.h"
#include "hal.h"
#include "proto_link.h"
#include "proto_msgs.h"
#include "proto_reply.h"

static struct {
    port_app_config_t cfg;
    proto_identity_t ident;
    bool reset_pending;
    uint32_t reset_at_us;
} app;

static size_t boot_error(uint8_t *out, uint8_t seq, uint8_t req, uint8_t code, uint16_t arg)
{
    return proto_reply_error(out, seq, req, code, arg, 1 /* application running */, 0);
}

/* Extension handler of proto_link: the application's side of the bootloader ids. */
static size_t app_boot_handler(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                               size_t cap)
{
    if (msg == NULL || out == NULL || len < PROTO_MSG_HDR || cap < PROTO_MSG_MAX ||
        msg[0] < 0x80u || msg[0] > 0x8Fu) {
        return 0;
    }
    if (msg[0] != PROTO_MSG_BOOT_ENTER || app.cfg.boot == NULL) {
        return boot_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_BOOT,
                          (uint16_t)BOOT_ERR_STATE);
    }
    if (len != PROTO_MSG_HDR + PROTO_BOOT_ENTER_LEN) {
        return boot_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_BAD_LENGTH, 0u);
    }
    drive_estop(); /* outputs off before the processor resets */
    boot_request_enter(app.cfg.boot);
    app.reset_pending = true;
    app.reset_at_us = now_us + PORT_RESET_DELAY_US;
    return proto_reply_ack(out, msg[1], msg[0]);
}

bool port_app_init(const port_app_config_t *c)
{
    boot_image_header_t h;
    unsigned caps = 0;

    if (c == NULL) {
        return false;
    }
    app.cfg = *c;
    app.reset_pending = false;
    app.ident.fw_version = c->fw_version;
    app.ident.build_id = 0u;
    if (c->boot != NULL && boot_check_app(c->boot, &h) == BOOT_REASON_APP_OK) {
        app.ident.fw_version = h.fw_version;
        app.ident.build_id = boot_image_get_u32(h.build_id);
    }
    if (c->serial) {
        caps |= 1u << PROTO_CAPABILITY_SERIAL;
    }
    if (c->can) {
        caps |= 1u << PROTO_CAPABILITY_CAN;
    }
    caps |= (1u << PROTO_CAPABILITY_TELEMETRY) | (1u << PROTO_CAPABILITY_JOG);
    if (c->boot != NULL) {
        caps |= 1u << PROTO_CAPABILITY_BOOTLOADER;
    }
    app.ident.capabilities = caps | c->capabilities;
    app.ident.tick_hz = c->tick_hz;
    app.ident.board_id = c->board_id;
    app.ident.planner_slots = 0u;
    app.ident.node_id = c->node_id;
    app.ident.axes = c->axes;
    if (!proto_link_init(&app.ident, c->serial, c->can)) {
        return false;
    }
    proto_link_set_ext_handler(app_boot_handler);
    return true;
}

uint32_t port_app_fw_version(void)
{
    return app.ident.fw_version;
}

void port_app_poll(void)
{
    calib_poll();
    drive_poll();
    proto_link_poll();
    hal_watchdog_kick();
    if (app.reset_pending) {
        uint32_t now = hal_time_us();

        /* a CAN reply may need several polls: give it the whole delay */
        if ((!app.cfg.can && port_uart_tx_idle()) || (int32_t)(now - app.reset_at_us) >= 0) {
            hal_system_reset();
        }
    }
}
