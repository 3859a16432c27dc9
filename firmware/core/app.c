/* app.c - the composition root (specification in app.h). */
#include "app.h"

#include "calib.h"
#include "comp2d_link.h"
#include "drive_excite.h"
#include "hal.h"
#include "param_store.h"
#include "proto_link.h"
#include "proto_msgs.h"
#include "proto_reply.h"

#if defined(__GNUC__)
#define APP_NOINLINE __attribute__((noinline))
#else
#define APP_NOINLINE
#endif

static struct {
    /* main */
    const boot_config_t *boot;
    bool link;
    bool can;
    proto_identity_t ident;
    bool reset_pending;
    uint32_t reset_at_us;
    uint16_t sessions; /* link sessions seen (a new one ends a calibration run) */
} app;

size_t app_boot_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out, size_t cap)
{
    if (msg == NULL || out == NULL || len < PROTO_MSG_HDR || cap < PROTO_MSG_MAX) {
        return 0;
    }
    if (msg[0] < 0x80u || msg[0] > 0x8Fu) {
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u,
                                 0, 0);
    }
    if (msg[0] != PROTO_MSG_BOOT_ENTER || app.boot == NULL) {
        /* lo = 1: application running */
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_BOOT,
                                 (uint16_t)BOOT_ERR_STATE, 1, 0);
    }
    if (len != PROTO_MSG_HDR + PROTO_BOOT_ENTER_LEN) {
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_BAD_LENGTH, 0u, 1,
                                 0);
    }
    drive_estop(); /* outputs off before the processor resets */
    boot_request_enter(app.boot);
    app.reset_pending = true;
    app.reset_at_us = now_us + APP_RESET_DELAY_US;
    return proto_reply_ack(out, msg[1], msg[0]);
}

static void identity(const app_board_t *b)
{
    boot_image_header_t h;
    uint32_t caps = (1u << PROTO_CAPABILITY_TELEMETRY) | (1u << PROTO_CAPABILITY_JOG) |
                    (1u << PROTO_CAPABILITY_CALIBRATION);

    app.ident.fw_version = b->fw_version;
    app.ident.build_id = b->build_id;
    if (b->boot != NULL && boot_check_app(b->boot, &h) == BOOT_REASON_APP_OK) {
        app.ident.fw_version = h.fw_version;
        app.ident.build_id = boot_image_get_u32(h.build_id);
    }
    if (b->serial) {
        caps |= 1u << PROTO_CAPABILITY_SERIAL;
    }
    if (b->can) {
        caps |= 1u << PROTO_CAPABILITY_CAN;
    }
    if (b->boot != NULL) {
        caps |= 1u << PROTO_CAPABILITY_BOOTLOADER;
    }
    app.ident.capabilities = caps | b->capabilities;
    app.ident.tick_hz = b->drive->tick_hz;
    app.ident.board_id = b->board_id;
    app.ident.planner_slots = 0u; /* the dispatcher reads it from the drive */
    app.ident.node_id = b->node_id;
    app.ident.axes = (uint8_t)b->drive->axes;
}

app_result_t app_init(const app_board_t *b)
{
    if (b == NULL || b->drive == NULL) {
        return APP_E_ARG;
    }
    app.boot = b->boot;
    app.link = b->serial || b->can;
    app.can = b->can;
    app.reset_pending = false;
    if (drive_init(b->drive) != DRIVE_OK) {
        return APP_E_DRIVE;
    }
    calib_init();       /* its tables from flash, installed in the drive's decoders */
    comp2d_link_init(); /* the 2-D map from flash, on calib's direction ramps */
    drive_excite_init();
    (void)param_store_load(); /* the saved parameters, all or none; status: param_store_status */
    identity(b);
    if (app.link) {
        if (!proto_link_init(&app.ident, b->serial, b->can)) {
            return APP_E_LINK;
        }
        proto_link_set_ext_handler(calib_handle);
        calib_set_next_handler(comp2d_link_handle);
        comp2d_link_set_next(drive_excite_handle);
        drive_excite_set_next_handler(app_boot_handle);
        app.sessions = proto_link_dispatch()->sessions;
    }
    hal_watchdog_start();
    return APP_OK;
}

uint32_t app_fw_version(void)
{
    return app.ident.fw_version;
}

/* The tick while an excitation experiment is armed (out of line: the usual
 * tick pays one flag test for it). */
static APP_NOINLINE void app_tick_excite(void)
{
    const drive_tick_out_t *t = drive_tick(true);

    if (t != NULL) {
        calib_tick(t->st, t->vel_ref);
        drive_excite_tick(t->st);
    }
}

void app_tick(void)
{
    const drive_tick_out_t *t;

    if (drive_excite_armed) {
        app_tick_excite();
        return;
    }
    /* the drive first; the calibration then sees what the drive published */
    t = drive_tick(calib_sampling());
    if (t != NULL) {
        calib_tick(t->st, t->vel_ref);
    }
}

void app_poll(void)
{
    calib_poll(); /* may queue a move: before the feed path takes blocks */
    drive_excite_poll();
    drive_poll();
    comp2d_link_poll(); /* re-anchor the tick's 2-D correction */
    if (app.link) {
        proto_link_poll();
        if (proto_link_dispatch()->sessions != app.sessions) {
            /* a run belongs to the session that started it */
            app.sessions = proto_link_dispatch()->sessions;
            calib_host_gone(PROTO_CALIB_STATUS_NEW_SESSION);
            drive_excite_host_gone(EXCITE_REASON_NEW_SESSION);
        }
    }
    hal_watchdog_kick();
    if (app.reset_pending) {
        /* a CAN reply may need several polls: give it the whole delay */
        if ((!app.can && hal_uart_tx_idle()) || (int32_t)(hal_time_us() - app.reset_at_us) >= 0) {
            app.reset_pending = false;
            hal_system_reset();
        }
    }
}
