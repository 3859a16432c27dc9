/* boot_sim.c - see boot_sim.h. */
#include "boot_sim.h"

#include "hal.h"
#include "hal_flash_sim.h"
#include "proto_link.h"
#include "proto_msgs.h"
#include "proto_reply.h"

static boot_t boot;
static boot_config_t cfg;
static volatile uint32_t request_word; /* survives a simulated reset */
static int mode = BOOT_SIM_BOOTLOADER;
static bool initialised;
static bool reset_pending;
static uint32_t resets;

static void on_jump(uint32_t load_addr, void *ctx)
{
    (void)load_addr;
    (void)ctx;
    mode = BOOT_SIM_APP;
}

static void on_reset(void *ctx)
{
    (void)ctx;
    reset_pending = true;
}

bool boot_sim_init(const char *flash_path, uint8_t node_id, uint32_t window_us)
{
    if (!flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE, FLASH_SIM_DEFAULT_PAGE,
                             FLASH_SIM_DEFAULT_WRITE)) {
        return false;
    }
    if (flash_path != NULL && flash_path[0] != '\0' && !flash_sim_attach(flash_path)) {
        return false;
    }
    boot_config_default(&cfg, BOOT_BOARD_SIM);
    cfg.window_us = window_us;
    cfg.node_id = node_id;
    cfg.request_word = &request_word;
    cfg.jump = on_jump;
    cfg.reset = on_reset;
    cfg.ctx = NULL;
    initialised = true;
    resets = 0u;
    (void)boot_sim_reset();
    resets = 0u;
    return boot.page_size != 0u;
}

int boot_sim_reset(void)
{
    if (!initialised) {
        return -1;
    }
    flash_sim_power_on();
    mode = BOOT_SIM_BOOTLOADER;
    reset_pending = false;
    resets++;
    if (boot_init(&boot, &cfg)) {
        (void)boot_start(&boot, hal_time_us());
    }
    return mode;
}

int boot_sim_mode(void)
{
    return mode;
}

int boot_sim_reason(void)
{
    return (int)boot.reason;
}

void boot_sim_poll(void)
{
    if (!initialised) {
        return;
    }
    if (mode == BOOT_SIM_BOOTLOADER) {
        uint8_t hb[8];

        (void)boot_poll(&boot, hal_time_us());
        if (mode == BOOT_SIM_BOOTLOADER && boot_heartbeat(&boot, hal_time_us(), hb)) {
            (void)hal_can_send(PROTO_CAN_ID(PROTO_CAN_FUNC_HEARTBEAT, cfg.node_id), hb, 8u);
        }
    }
    if (reset_pending) {
        (void)boot_sim_reset();
    }
}

size_t boot_sim_app_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                           size_t cap)
{
    (void)now_us;
    if (msg == NULL || out == NULL || len < PROTO_MSG_HDR || cap < PROTO_MSG_MAX) {
        return 0;
    }
    if (msg[0] < 0x80u || msg[0] > 0x8Fu) {
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u,
                                 0, 0);
    }
    if (msg[0] != PROTO_MSG_BOOT_ENTER) {
        /* lo = 1: application running */
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_BOOT,
                                 (uint16_t)BOOT_ERR_STATE, 1, 0);
    }
    if (len != PROTO_MSG_HDR + PROTO_BOOT_ENTER_LEN) {
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_BAD_LENGTH, 0u, 1,
                                 0);
    }
    boot_request_enter(&cfg);
    reset_pending = true;
    hal_system_reset();
    return proto_reply_ack(out, msg[1], msg[0]);
}

size_t boot_sim_handle(const uint8_t *msg, size_t len, uint8_t *out, size_t cap)
{
    size_t n;

    if (!initialised) {
        return 0;
    }
    if (mode == BOOT_SIM_APP) {
        return boot_sim_app_handle(msg, len, hal_time_us(), out, cap);
    }
    n = boot_handle(&boot, msg, len, out, cap);
    return n;
}

size_t boot_sim_link_handle(const uint8_t *msg, size_t len, uint32_t now_us, uint8_t *out,
                            size_t cap)
{
    (void)now_us;
    return boot_sim_handle(msg, len, out, cap);
}

uint32_t boot_sim_app_version(void)
{
    boot_image_header_t h;

    if (!initialised || boot_check_app(&cfg, &h) != BOOT_REASON_APP_OK) {
        return 0u;
    }
    return h.fw_version;
}

uint32_t boot_sim_app_build_id(void)
{
    boot_image_header_t h;

    if (!initialised || boot_check_app(&cfg, &h) != BOOT_REASON_APP_OK) {
        return 0u;
    }
    return (uint32_t)h.build_id[0] | ((uint32_t)h.build_id[1] << 8) |
           ((uint32_t)h.build_id[2] << 16) | ((uint32_t)h.build_id[3] << 24);
}

size_t boot_sim_drive_handle(const uint8_t *msg, size_t len, uint8_t *out, size_t cap)
{
    size_t n;

    if (!initialised || msg == NULL || out == NULL || len < PROTO_MSG_HDR || cap < BOOT_REPLY_MAX) {
        return 0;
    }
    if (mode == BOOT_SIM_APP && msg[0] == PROTO_MSG_IDENTIFY) {
        proto_identify_reply_t r;
        r.fw_version = boot_sim_app_version();
        r.build_id = 0u;
        r.protocol_version = PROTO_VERSION;
        r.axes = 3u;
        r.node_id = cfg.node_id;
        r.capabilities = (1u << PROTO_CAPABILITY_SERIAL) | (1u << PROTO_CAPABILITY_CAN) |
                         (1u << PROTO_CAPABILITY_SIMULATED);
        r.tick_hz = 10000u;
        r.planner_slots = 32u;
        r.max_payload = PROTO_MAX_PAYLOAD;
        r.board_id = (uint16_t)cfg.board_id;
        out[0] = (uint8_t)PROTO_MSG_IDENTIFY_REPLY;
        out[1] = msg[1];
        return PROTO_MSG_HDR +
               proto_identify_reply_encode(&r, out + PROTO_MSG_HDR, cap - PROTO_MSG_HDR);
    }
    n = boot_sim_handle(msg, len, out, cap);
    if (n == 0u && mode == BOOT_SIM_APP) {
        return proto_reply_error(out, msg[1], msg[0], (uint8_t)PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u,
                                 0, 0);
    }
    return n;
}

bool boot_sim_serve_link(void)
{
    proto_identity_t id = {0};

    if (!initialised) {
        return false;
    }
    id.node_id = cfg.node_id;
    id.axes = 1u;
    id.tick_hz = 1000u;
    id.board_id = cfg.board_id;
    id.planner_slots = 1u;
    if (!proto_link_init(&id, true, true)) {
        return false;
    }
    proto_link_set_ext_handler(boot_sim_link_handle);
    proto_link_set_ext_exclusive(true);
    return true;
}

const boot_config_t *boot_sim_config(void)
{
    return &cfg;
}

uint32_t boot_sim_resets(void)
{
    return resets;
}
