/*
 * Bootloader: image header, boot decision, flashing session and fault
 * injection, in process. The "host" here is a fake transport that calls
 * boot_handle with the wire encoding of boot.h; the drive's flash is the
 * simulator's (firmware/ports/sim/hal_flash_sim.c) with strict page rules.
 */
#include <stdio.h>
#include <string.h>

#include "boot/boot.h"
#include "crc.h"
#include "hal.h"
#include "hal_flash_sim.h"
#include "proto_msgs.h"
#include "unity.h"

#define BASE   0x08010000u
#define SIZE   (16u * 1024u)
#define PAGE   256u
#define WSIZE  8u
#define SLOT   (SIZE - 1024u)
#define LOAD   (BASE + BOOT_IMAGE_HDR_AREA)
#define BOARD  BOOT_BOARD_SIM
#define MAXLEN (SLOT - BOOT_IMAGE_HDR_AREA)

static boot_t boot;
static boot_config_t cfg;
static volatile uint32_t request_word;
static unsigned jumps;
static uint32_t jumped_to;
static unsigned resets;

static uint8_t old_payload[MAXLEN + 256u];
static uint8_t new_payload[MAXLEN + 256u];
static uint8_t old_hdr[BOOT_IMAGE_HDR_SIZE];
static uint8_t new_hdr[BOOT_IMAGE_HDR_SIZE];
#define OLD_LEN 4000u
#define NEW_LEN 6001u /* not a multiple of the write unit: short last block */

static void on_jump(uint32_t load_addr, void *ctx)
{
    (void)ctx;
    jumps++;
    jumped_to = load_addr;
}

static void on_reset(void *ctx)
{
    (void)ctx;
    resets++;
}

static void make_header(uint8_t raw[BOOT_IMAGE_HDR_SIZE], const uint8_t *payload, uint32_t len,
                        uint32_t version, uint32_t board, uint32_t load)
{
    boot_image_header_t h;
    unsigned i;

    memset(&h, 0, sizeof h);
    h.magic = BOOT_IMAGE_MAGIC;
    h.format_version = BOOT_IMAGE_FORMAT_VERSION;
    h.header_size = BOOT_IMAGE_HDR_SIZE;
    h.board_id = board;
    h.fw_version = version;
    h.load_addr = load;
    h.length = len;
    h.payload_crc = crc32_update(CRC32_INIT, payload, len);
    for (i = 0; i < BOOT_IMAGE_BUILD_ID_LEN; i++) {
        h.build_id[i] = (uint8_t)(0xB0u + i);
    }
    boot_image_encode(&h, raw);
}

/* Simulated reset: power back, the bootloader starts from scratch. */
static boot_reason_t reset_drive(void)
{
    flash_sim_power_on();
    TEST_ASSERT_TRUE(boot_init(&boot, &cfg));
    return boot_start(&boot, 0u);
}

void setUp(void)
{
    unsigned i;

    TEST_ASSERT_TRUE(flash_sim_configure(BASE, SIZE, PAGE, WSIZE));
    memset(&cfg, 0, sizeof cfg);
    cfg.board_id = BOARD;
    cfg.slot_base = BASE;
    cfg.slot_size = SLOT;
    cfg.window_us = 0u;
    cfg.request_word = &request_word;
    cfg.jump = on_jump;
    cfg.reset = on_reset;
    request_word = 0u;
    jumps = 0u;
    resets = 0u;
    jumped_to = 0u;
    for (i = 0; i < MAXLEN; i++) {
        old_payload[i] = (uint8_t)(i * 7u + 3u);
        new_payload[i] = (uint8_t)((i * 2654435761u) >> 13);
    }
    make_header(old_hdr, old_payload, OLD_LEN, 0x00010000u, BOARD, LOAD);
    make_header(new_hdr, new_payload, NEW_LEN, 0x00020001u, BOARD, LOAD);
    TEST_ASSERT_TRUE(boot_init(&boot, &cfg));
}

void tearDown(void)
{
}

/* ---- fake transport: the host side, with the generated codecs ----------- */

#define ERR_GENERIC 1000 /* + error_code for errors other than `boot` */

static uint8_t rsp[BOOT_REPLY_MAX];
static size_t rsp_len;
static uint8_t seq;

/* Send msg_id + payload; returns 0 (ok), a boot_status_t, or ERR_GENERIC + code. */
static int xfer_seq(uint8_t id, uint8_t s, const uint8_t *payload, size_t n)
{
    uint8_t msg[PROTO_MSG_MAX];
    proto_error_t e;

    msg[0] = id;
    msg[1] = s;
    if (n > 0u) {
        memcpy(msg + 2, payload, n);
    }
    rsp_len = boot_handle(&boot, msg, n + 2u, rsp, sizeof rsp);
    TEST_ASSERT_TRUE(rsp_len >= 2u);
    TEST_ASSERT_EQUAL_INT(s, rsp[1]);
    if (rsp[0] != PROTO_MSG_ERROR) {
        const proto_msg_info_t *req = proto_msg_info(id);
        TEST_ASSERT_NOT_NULL(req);
        TEST_ASSERT_EQUAL_INT(req->reply, rsp[0]);
        return 0;
    }
    TEST_ASSERT_TRUE(proto_error_decode(rsp + 2, rsp_len - 2u, &e));
    TEST_ASSERT_EQUAL_INT(id, e.req);
    if (e.code == PROTO_ERROR_CODE_BOOT) {
        TEST_ASSERT_NOT_EQUAL(0, e.arg);
        return (int)e.arg;
    }
    return ERR_GENERIC + (int)e.code;
}

static int xfer(uint8_t id, const uint8_t *payload, size_t n)
{
    return xfer_seq(id, ++seq, payload, n);
}

static int host_simple(uint8_t id)
{
    return xfer(id, NULL, 0);
}

static int host_erase(const uint8_t hdr[BOOT_IMAGE_HDR_SIZE])
{
    proto_boot_erase_t m;
    uint8_t p[PROTO_MAX_PAYLOAD];
    memcpy(m.header, hdr, BOOT_IMAGE_HDR_SIZE);
    return xfer(PROTO_MSG_BOOT_ERASE, p, proto_boot_erase_encode(&m, p, sizeof p));
}

static int host_write(uint32_t addr, const uint8_t *data, size_t len)
{
    proto_boot_write_t m;
    proto_boot_written_t r;
    uint8_t p[PROTO_MAX_PAYLOAD];
    int st;
    m.addr = addr;
    m.data_len = (uint16_t)len;
    memcpy(m.data, data, len);
    st = xfer(PROTO_MSG_BOOT_WRITE, p, proto_boot_write_encode(&m, p, sizeof p));
    if (st == 0) {
        /* address and length echo */
        TEST_ASSERT_TRUE(proto_boot_written_decode(rsp + 2, rsp_len - 2u, &r));
        TEST_ASSERT_EQUAL_HEX32(addr, r.addr);
        TEST_ASSERT_EQUAL_UINT16(len, r.len);
    }
    return st;
}

static int host_crc(uint32_t addr, uint32_t len, uint32_t *crc)
{
    proto_boot_crc_t m;
    proto_boot_crc_value_t r;
    uint8_t p[PROTO_MAX_PAYLOAD];
    int st;
    m.addr = addr;
    m.len = len;
    st = xfer(PROTO_MSG_BOOT_CRC, p, proto_boot_crc_encode(&m, p, sizeof p));
    *crc = 0u;
    if (st == 0) {
        TEST_ASSERT_TRUE(proto_boot_crc_value_decode(rsp + 2, rsp_len - 2u, &r));
        *crc = r.crc;
    }
    return st;
}

/* Runs a whole flashing session; stops (host killed / link dropped) before
 * block `stop_block` when >= 0. Returns false when a flash operation failed
 * (power cut), true when the session ran to the requested point. */
static bool host_flash(const uint8_t *hdr, const uint8_t *payload, uint32_t len, unsigned block,
                       long stop_block, bool finish)
{
    uint32_t off;
    long n = 0;
    uint32_t crc;

    if (host_simple(PROTO_MSG_BOOT_CONNECT) != BOOT_OK) {
        return false;
    }
    if (host_erase(hdr) != BOOT_OK) {
        return false;
    }
    for (off = 0; off < len; off += block, n++) {
        uint32_t k = len - off < block ? len - off : block;
        if (stop_block >= 0 && n == stop_block) {
            return true;
        }
        if (host_write(LOAD + off, payload + off, k) != BOOT_OK) {
            return false;
        }
    }
    if (stop_block >= 0 && n == stop_block) {
        return true;
    }
    if (host_crc(LOAD, len, &crc) != BOOT_OK) {
        return false;
    }
    TEST_ASSERT_EQUAL_HEX32(crc32_update(CRC32_INIT, payload, len), crc);
    if (!finish) {
        return true;
    }
    return host_simple(PROTO_MSG_BOOT_FINISH) == BOOT_OK;
}

static bool flash_payload_is(const uint8_t *payload, uint32_t len)
{
    static uint8_t buf[MAXLEN];
    TEST_ASSERT_TRUE(hal_flash_read(LOAD, buf, len));
    return memcmp(buf, payload, len) == 0;
}

static void install_old(void)
{
    TEST_ASSERT_TRUE(host_flash(old_hdr, old_payload, OLD_LEN, BOOT_BLOCK_MAX, -1, true));
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    jumps = 0u;
}

/* After any interruption: the drive is in its bootloader or runs a valid image
 * (old or new, never corrupt), and a second flash always succeeds. */
static boot_reason_t assert_recoverable(void)
{
    boot_reason_t r = reset_drive();
    boot_image_header_t h;

    if (r == BOOT_REASON_APP_OK) {
        TEST_ASSERT_EQUAL_UINT32(1u, jumps);
        TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, boot_check_app(&cfg, &h));
        if (h.fw_version == 0x00020001u) {
            TEST_ASSERT_TRUE(flash_payload_is(new_payload, NEW_LEN));
        } else {
            TEST_ASSERT_EQUAL_HEX32(0x00010000u, h.fw_version);
            TEST_ASSERT_TRUE(flash_payload_is(old_payload, OLD_LEN));
        }
    } else {
        TEST_ASSERT_EQUAL_UINT32(0u, jumps);
        TEST_ASSERT_EQUAL(BOOT_MODE_STAY, boot.mode);
    }
    TEST_ASSERT_TRUE(host_flash(new_hdr, new_payload, NEW_LEN, BOOT_BLOCK_MAX, -1, true));
    jumps = 0u;
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    TEST_ASSERT_EQUAL_UINT32(1u, jumps);
    TEST_ASSERT_TRUE(flash_payload_is(new_payload, NEW_LEN));
    return r;
}

/* ---- image header --------------------------------------------------------- */

static void test_image_roundtrip_and_specific_errors(void)
{
    uint8_t raw[BOOT_IMAGE_HDR_SIZE];
    boot_image_header_t h;

    memcpy(raw, new_hdr, sizeof raw);
    TEST_ASSERT_EQUAL(BOOT_IMAGE_OK, boot_image_parse(raw, &h));
    TEST_ASSERT_EQUAL_HEX32(0x00020001u, h.fw_version);
    TEST_ASSERT_EQUAL_UINT32(NEW_LEN, h.length);
    TEST_ASSERT_EQUAL_UINT32(LOAD, h.load_addr);
    TEST_ASSERT_EQUAL_INT(0xB3u, h.build_id[3]);
    TEST_ASSERT_EQUAL(BOOT_IMAGE_OK, boot_image_check(&h, BOARD, LOAD, MAXLEN));
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_BOARD, boot_image_check(&h, BOARD + 1u, LOAD, MAXLEN));
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_LOAD_ADDR, boot_image_check(&h, BOARD, LOAD + 8u, MAXLEN));
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_LENGTH, boot_image_check(&h, BOARD, LOAD, NEW_LEN - 1u));
    h.length = 0u;
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_LENGTH, boot_image_check(&h, BOARD, LOAD, MAXLEN));

    raw[0] ^= 1u;
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_MAGIC, boot_image_parse(raw, &h));
    memcpy(raw, new_hdr, sizeof raw);
    raw[4] = 2u;
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_VERSION, boot_image_parse(raw, &h));
    memcpy(raw, new_hdr, sizeof raw);
    raw[6] = 65u;
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_VERSION, boot_image_parse(raw, &h));
    memcpy(raw, new_hdr, sizeof raw);
    raw[13] ^= 0x10u; /* version byte: header CRC catches it */
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_HDR_CRC, boot_image_parse(raw, &h));
    memcpy(raw, new_hdr, sizeof raw);
    raw[61] ^= 0x01u; /* the CRC itself */
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_HDR_CRC, boot_image_parse(raw, &h));
}

static void test_image_reserved_must_be_zero(void)
{
    uint8_t raw[BOOT_IMAGE_HDR_SIZE];
    boot_image_header_t h;

    memcpy(raw, new_hdr, sizeof raw);
    raw[50] = 1u;
    boot_image_put_u32(raw + 60, crc32_update(CRC32_INIT, raw, 60));
    TEST_ASSERT_EQUAL(BOOT_IMAGE_ERR_RESERVED, boot_image_parse(raw, &h));
}

/* ---- boot decision -------------------------------------------------------- */

static void test_erased_flash_stays_in_bootloader(void)
{
    TEST_ASSERT_EQUAL(BOOT_REASON_NO_APP, reset_drive());
    TEST_ASSERT_EQUAL(BOOT_MODE_STAY, boot.mode);
    TEST_ASSERT_EQUAL(BOOT_ACT_NONE, boot_poll(&boot, 1000000000u));
    TEST_ASSERT_EQUAL_UINT32(0u, jumps);
}

static void test_full_flash_then_boot_jumps_to_load_address(void)
{
    boot_ident_t id;

    TEST_ASSERT_TRUE(host_flash(new_hdr, new_payload, NEW_LEN, BOOT_BLOCK_MAX, -1, true));
    TEST_ASSERT_EQUAL_UINT32(0u, flash_sim_stats()->violations);
    TEST_ASSERT_EQUAL(BOOT_OK, host_simple(PROTO_MSG_BOOT_REBOOT));
    TEST_ASSERT_EQUAL_UINT32(0u, resets);
    TEST_ASSERT_EQUAL(BOOT_ACT_RESET, boot_poll(&boot, 0u));
    TEST_ASSERT_EQUAL_UINT32(1u, resets);
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    TEST_ASSERT_EQUAL_UINT32(1u, jumps);
    TEST_ASSERT_EQUAL_HEX32(LOAD, jumped_to);
    TEST_ASSERT_TRUE(flash_payload_is(new_payload, NEW_LEN));
    boot_identify(&boot, &id);
    TEST_ASSERT_EQUAL_HEX32(0x00020001u, id.app_version);
    TEST_ASSERT_EQUAL_UINT32(NEW_LEN, id.app_length);
    TEST_ASSERT_EQUAL_INT(BOOT_REASON_APP_OK, id.reason);
}

static void test_connect_reports_layout(void)
{
    proto_boot_info_t r;

    TEST_ASSERT_EQUAL_INT(0, host_simple(PROTO_MSG_BOOT_CONNECT));
    TEST_ASSERT_EQUAL_UINT(2u + PROTO_BOOT_INFO_LEN, rsp_len);
    TEST_ASSERT_TRUE(proto_boot_info_decode(rsp + 2, rsp_len - 2u, &r));
    TEST_ASSERT_EQUAL_HEX32(BOOT_VERSION, r.boot_version);
    TEST_ASSERT_EQUAL_HEX32(BOARD, r.board_id);
    TEST_ASSERT_EQUAL_HEX32(BASE, r.slot_base);
    TEST_ASSERT_EQUAL_UINT32(SLOT, r.slot_size);
    TEST_ASSERT_EQUAL_UINT32(PAGE, r.page_size);
    TEST_ASSERT_EQUAL_UINT32(WSIZE, r.write_size);
    TEST_ASSERT_EQUAL_HEX32(LOAD, r.load_addr);
    TEST_ASSERT_EQUAL_UINT32(MAXLEN, r.max_length);
    TEST_ASSERT_EQUAL_UINT16(BOOT_BLOCK_MAX, r.block_max);
    TEST_ASSERT_EQUAL_INT(BOOT_REASON_NO_APP, r.app_state);
    TEST_ASSERT_EQUAL_INT(BOOT_SESSION_IDLE, r.session);
}

static void test_identify_in_bootloader_and_unknown_ids(void)
{
    proto_identify_reply_t r;
    uint8_t msg[2] = {PROTO_MSG_BOOT_INFO, 9u};

    cfg.node_id = 7u;
    TEST_ASSERT_TRUE(boot_init(&boot, &cfg));
    TEST_ASSERT_EQUAL_INT(0, host_simple(PROTO_MSG_IDENTIFY));
    TEST_ASSERT_TRUE(proto_identify_reply_decode(rsp + 2, rsp_len - 2u, &r));
    TEST_ASSERT_EQUAL_UINT8(0u, r.axes);
    TEST_ASSERT_EQUAL_UINT8(7u, r.node_id);
    TEST_ASSERT_EQUAL_UINT16(BOARD, r.board_id);
    TEST_ASSERT_EQUAL_HEX32(BOOT_VERSION, r.fw_version);
    TEST_ASSERT_TRUE((r.capabilities & (1u << PROTO_CAPABILITY_BOOTLOADER)) != 0u);
    TEST_ASSERT_EQUAL_INT(ERR_GENERIC + PROTO_ERROR_CODE_UNKNOWN_MESSAGE, host_simple(0x8Eu));
    TEST_ASSERT_EQUAL_INT(ERR_GENERIC + PROTO_ERROR_CODE_UNKNOWN_MESSAGE,
                          host_simple(PROTO_MSG_QUEUE_BLOCK));
    TEST_ASSERT_EQUAL_INT(ERR_GENERIC + PROTO_ERROR_CODE_BAD_LENGTH,
                          xfer(PROTO_MSG_BOOT_CONNECT, msg, 1));
    /* a drive-to-host message is never answered (no echo loops) */
    TEST_ASSERT_EQUAL_UINT(0u, boot_handle(&boot, msg, 2, rsp, sizeof rsp));
    TEST_ASSERT_EQUAL_UINT(0u, boot_handle(&boot, msg, 1, rsp, sizeof rsp));
}

static void test_repeated_request_is_answered_from_cache_not_executed(void)
{
    proto_boot_erase_t m;
    uint8_t p[PROTO_MAX_PAYLOAD];
    size_t n;
    uint8_t s0;

    memcpy(m.header, new_hdr, BOOT_IMAGE_HDR_SIZE);
    n = proto_boot_erase_encode(&m, p, sizeof p);
    s0 = ++seq;
    TEST_ASSERT_EQUAL_INT(0, xfer_seq(PROTO_MSG_BOOT_ERASE, s0, p, n));
    TEST_ASSERT_EQUAL_INT(0, host_write(LOAD, new_payload, 64));
    /* an old erase frame replayed (same seq) after other traffic runs again... */
    flash_sim_stats_reset();
    TEST_ASSERT_EQUAL_INT(0, xfer_seq(PROTO_MSG_BOOT_ERASE, s0, p, n));
    TEST_ASSERT_TRUE(flash_sim_stats()->erases > 0u);
    /* ...but a retry of the last request (reply lost) is not executed again */
    TEST_ASSERT_EQUAL_INT(0, host_write(LOAD, new_payload, 64));
    flash_sim_stats_reset();
    TEST_ASSERT_EQUAL_INT(0, xfer_seq(PROTO_MSG_BOOT_ERASE, ++seq, p, n));
    TEST_ASSERT_EQUAL_INT(0, xfer_seq(PROTO_MSG_BOOT_ERASE, seq, p, n));
    TEST_ASSERT_EQUAL_UINT32(26u, flash_sim_stats()->erases); /* (512 + 6001) / 256: once */
}

static void test_window_then_jump_and_host_connect_cancels_it(void)
{
    install_old();
    cfg.window_us = 1000u;
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    TEST_ASSERT_EQUAL(BOOT_MODE_WINDOW, boot.mode);
    TEST_ASSERT_EQUAL(BOOT_ACT_NONE, boot_poll(&boot, 999u));
    TEST_ASSERT_EQUAL(BOOT_ACT_JUMP, boot_poll(&boot, 1000u));
    TEST_ASSERT_EQUAL_UINT32(1u, jumps);

    jumps = 0u;
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    TEST_ASSERT_EQUAL(BOOT_OK, host_simple(PROTO_MSG_BOOT_CONNECT));
    TEST_ASSERT_EQUAL(BOOT_MODE_STAY, boot.mode);
    TEST_ASSERT_EQUAL(BOOT_ACT_NONE, boot_poll(&boot, 5000000u));
    TEST_ASSERT_EQUAL_UINT32(0u, jumps);
}

static void test_host_request_word_is_honoured_once(void)
{
    install_old();
    boot_request_enter(&cfg);
    TEST_ASSERT_EQUAL(BOOT_REASON_REQUESTED, reset_drive());
    TEST_ASSERT_EQUAL_UINT32(0u, jumps);
    TEST_ASSERT_EQUAL_HEX32(0u, request_word);
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    TEST_ASSERT_EQUAL_UINT32(1u, jumps);
}

static void test_application_marked_bad_stays(void)
{
    install_old();
    TEST_ASSERT_TRUE(boot_app_mark_bad(&cfg));
    TEST_ASSERT_TRUE(boot_app_mark_bad(&cfg)); /* idempotent */
    TEST_ASSERT_EQUAL(BOOT_REASON_MARKED_BAD, reset_drive());
    TEST_ASSERT_EQUAL_UINT32(0u, jumps);
    TEST_ASSERT_EQUAL_UINT32(0u, flash_sim_stats()->violations);
    (void)assert_recoverable();
}

static void test_mark_bad_interrupted_still_stays_or_runs_valid(void)
{
    long cut;
    for (cut = 0; cut < 8; cut++) {
        boot_reason_t r;
        install_old();
        flash_sim_power_cut_after(cut);
        TEST_ASSERT_FALSE(boot_app_mark_bad(&cfg));
        r = reset_drive();
        /* a partial BAD marker is still a BAD marker: conservative */
        TEST_ASSERT_EQUAL(cut == 0 ? BOOT_REASON_APP_OK : BOOT_REASON_MARKED_BAD, r);
    }
}

static void test_payload_bit_flip_in_flash_is_caught_at_boot(void)
{
    uint8_t b;
    install_old();
    TEST_ASSERT_TRUE(hal_flash_read(LOAD + 1234u, &b, 1));
    TEST_ASSERT_TRUE(flash_sim_poke(LOAD + 1234u, (uint8_t)(b ^ 0x04u)));
    TEST_ASSERT_EQUAL(BOOT_REASON_CRC, reset_drive());
    TEST_ASSERT_EQUAL_UINT32(0u, jumps);
}

static void test_header_or_marker_corruption_is_caught_at_boot(void)
{
    uint8_t b;
    install_old();
    TEST_ASSERT_TRUE(hal_flash_read(BASE + 20u, &b, 1)); /* length field */
    TEST_ASSERT_TRUE(flash_sim_poke(BASE + 20u, (uint8_t)(b ^ 0x01u)));
    TEST_ASSERT_EQUAL(BOOT_REASON_BAD_HEADER, reset_drive());
    TEST_ASSERT_TRUE(flash_sim_poke(BASE + 20u, b));
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    TEST_ASSERT_TRUE(hal_flash_read(BASE + BOOT_MARK_VALID_OFF + 5u, &b, 1));
    TEST_ASSERT_TRUE(flash_sim_poke(BASE + BOOT_MARK_VALID_OFF + 5u, (uint8_t)(b ^ 0x80u)));
    TEST_ASSERT_EQUAL(BOOT_REASON_NOT_VALIDATED, reset_drive());
}

/* ---- session rules -------------------------------------------------------- */

static void test_bad_images_refused_before_anything_is_erased(void)
{
    uint8_t raw[BOOT_IMAGE_HDR_SIZE];
    struct {
        uint32_t board, load, len;
        uint8_t expect;
    } cases[] = {
        {BOARD + 1u, LOAD, NEW_LEN, BOOT_IMAGE_ERR_BOARD},
        {BOARD, LOAD + 0x100u, NEW_LEN, BOOT_IMAGE_ERR_LOAD_ADDR},
        {BOARD, LOAD, MAXLEN + 1u, BOOT_IMAGE_ERR_LENGTH},
        {BOARD, LOAD, 0u, BOOT_IMAGE_ERR_LENGTH},
    };
    unsigned i;

    install_old();
    flash_sim_stats_reset();
    for (i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        make_header(raw, new_payload, cases[i].len, 0x00020001u, cases[i].board, cases[i].load);
        TEST_ASSERT_EQUAL_INT(cases[i].expect, host_erase(raw));
    }
    memcpy(raw, new_hdr, sizeof raw);
    raw[30] ^= 0x40u; /* build id: header CRC */
    TEST_ASSERT_EQUAL_INT(BOOT_IMAGE_ERR_HDR_CRC, host_erase(raw));
    memcpy(raw, new_hdr, sizeof raw);
    raw[1] = 'X';
    TEST_ASSERT_EQUAL_INT(BOOT_IMAGE_ERR_MAGIC, host_erase(raw));
    TEST_ASSERT_EQUAL_UINT32(0u, flash_sim_stats()->erases);
    TEST_ASSERT_EQUAL_UINT32(0u, flash_sim_stats()->writes);
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    TEST_ASSERT_TRUE(flash_payload_is(old_payload, OLD_LEN));
}

static void test_write_rules(void)
{
    uint8_t data[BOOT_BLOCK_MAX + 1u];

    memset(data, 0x5A, sizeof data);
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_STATE, host_write(LOAD, data, 16));
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_STATE, host_simple(PROTO_MSG_BOOT_FINISH));
    TEST_ASSERT_EQUAL_INT(BOOT_OK, host_erase(new_hdr));
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_RANGE, host_write(LOAD - 8u, data, 8));
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_RANGE, host_write(LOAD + NEW_LEN - 8u, data, 16));
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_RANGE, host_write(0xFFFFFFF8u, data, 16));
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_ALIGN, host_write(LOAD + 4u, data, 8));
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_ALIGN, host_write(LOAD, data, 12));
    TEST_ASSERT_EQUAL_UINT32(0u, flash_sim_stats()->writes);
    /* a block without data, or too long for the message: refused */
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_MALFORMED, host_write(LOAD, data, 0));
    TEST_ASSERT_EQUAL(BOOT_ERR_MALFORMED, boot_write(&boot, LOAD, data, BOOT_BLOCK_MAX + 1u));
    {
        uint8_t p[PROTO_MAX_PAYLOAD];
        memset(p, 0, sizeof p);
        TEST_ASSERT_EQUAL_INT(ERR_GENERIC + PROTO_ERROR_CODE_BAD_LENGTH,
                              xfer(PROTO_MSG_BOOT_WRITE, p, 4u + BOOT_BLOCK_MAX + 1u));
    }
    /* retry of the same block after a lost reply: fine */
    TEST_ASSERT_EQUAL_INT(BOOT_OK, host_write(LOAD, new_payload, 64));
    TEST_ASSERT_EQUAL_INT(BOOT_OK, host_write(LOAD, new_payload, 64));
    /* different data over it: refused, nothing changed */
    flash_sim_stats_reset();
    memcpy(data, new_payload, 64);
    data[63] ^= 1u;
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_NOT_ERASED, host_write(LOAD, data, 64));
    TEST_ASSERT_EQUAL_UINT32(0u, flash_sim_stats()->writes);
    TEST_ASSERT_TRUE(flash_payload_is(new_payload, 64));
    /* last block may be short */
    TEST_ASSERT_EQUAL_INT(
        BOOT_OK, host_write(LOAD + NEW_LEN - 1u - 8u * 10u, new_payload + NEW_LEN - 81u, 81));
    TEST_ASSERT_EQUAL_UINT32(0u, flash_sim_stats()->violations);
}

static void test_finish_with_missing_block_is_refused_and_not_valid(void)
{
    uint32_t off;
    install_old();
    TEST_ASSERT_EQUAL_INT(BOOT_OK, host_erase(new_hdr));
    for (off = 0; off < NEW_LEN; off += BOOT_BLOCK_MAX) {
        uint32_t k = NEW_LEN - off < BOOT_BLOCK_MAX ? NEW_LEN - off : BOOT_BLOCK_MAX;
        if (off == 5u * BOOT_BLOCK_MAX) {
            continue;
        }
        TEST_ASSERT_EQUAL_INT(BOOT_OK, host_write(LOAD + off, new_payload + off, k));
    }
    TEST_ASSERT_EQUAL_INT(BOOT_IMAGE_ERR_PAYLOAD_CRC, host_simple(PROTO_MSG_BOOT_FINISH));
    TEST_ASSERT_EQUAL(BOOT_REASON_NO_APP, reset_drive());
    /* the missing block can still be written in a new session after the reset? no:
     * the session died with the reset; a new ERASE is required */
    TEST_ASSERT_EQUAL_INT(BOOT_ERR_STATE, host_write(LOAD + 5u * BOOT_BLOCK_MAX, new_payload, 8));
    (void)assert_recoverable();
}

static void test_bit_flip_in_transit_detected_by_final_crc(void)
{
    static uint8_t corrupt[MAXLEN];
    unsigned bit;
    unsigned caught = 0;

    for (bit = 0; bit < 64u; bit++) {
        uint32_t pos = (bit * 977u) % NEW_LEN;
        memcpy(corrupt, new_payload, NEW_LEN);
        corrupt[pos] ^= (uint8_t)(1u << (bit % 8u));
        TEST_ASSERT_TRUE(flash_sim_configure(BASE, SIZE, PAGE, WSIZE));
        TEST_ASSERT_TRUE(boot_init(&boot, &cfg));
        /* the header announces new_payload's CRC, the wire delivered corrupt */
        TEST_ASSERT_TRUE(host_flash(new_hdr, corrupt, NEW_LEN, BOOT_BLOCK_MAX, NEW_LEN, false));
        if (host_simple(PROTO_MSG_BOOT_FINISH) == BOOT_IMAGE_ERR_PAYLOAD_CRC) {
            caught++;
        }
        TEST_ASSERT_NOT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    }
    TEST_ASSERT_EQUAL_UINT(64u, caught);
}

/* ---- fault injection ------------------------------------------------------ */

/* The host dies (or the link drops) before every block of the transfer, and
 * after the last block before FINISH; then the drive is reset. */
static void test_interrupt_at_every_block_boundary(void)
{
    long nblocks = (long)((NEW_LEN + BOOT_BLOCK_MAX - 1u) / BOOT_BLOCK_MAX);
    long stop;
    unsigned points = 0;

    for (stop = 0; stop <= nblocks; stop++) {
        install_old();
        TEST_ASSERT_TRUE(host_flash(new_hdr, new_payload, NEW_LEN, BOOT_BLOCK_MAX, stop, true));
        TEST_ASSERT_NOT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
        (void)assert_recoverable();
        points++;
    }
    /* before ERASE: the old application must still run */
    install_old();
    TEST_ASSERT_EQUAL(BOOT_OK, host_simple(PROTO_MSG_BOOT_CONNECT));
    TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
    TEST_ASSERT_TRUE(flash_payload_is(old_payload, OLD_LEN));
    points++;
    printf("boot: host/link interrupted at %u points (every block boundary), %u recovered\n",
           points, points);
}

/* Power is cut after n flash bytes (erase or program) for n spread over the
 * whole session, including every byte of the header and marker writes. */
static void test_power_cut_at_random_bytes_never_runs_a_corrupt_image(void)
{
    long total;
    long n;
    unsigned points = 0;
    unsigned new_ok = 0;
    unsigned stayed = 0;
    uint32_t seed = 12345u;

    install_old();
    flash_sim_stats_reset();
    TEST_ASSERT_TRUE(host_flash(new_hdr, new_payload, NEW_LEN, BOOT_BLOCK_MAX, -1, true));
    total = (long)flash_sim_stats()->erases * (long)PAGE + (long)flash_sim_stats()->bytes;

    for (n = 0; n < total + 2; n += 1 + (long)((seed >> 16) % 97u)) {
        seed = seed * 1103515245u + 12345u;
        install_old();
        flash_sim_power_cut_after(n);
        (void)host_flash(new_hdr, new_payload, NEW_LEN, BOOT_BLOCK_MAX, -1, true);
        if (assert_recoverable() == BOOT_REASON_APP_OK) {
            new_ok++;
        } else {
            stayed++;
        }
        points++;
    }
    /* every byte of FINISH (header 64 + marker 8) */
    for (n = total - 72; n <= total; n++) {
        install_old();
        flash_sim_power_cut_after(n);
        (void)host_flash(new_hdr, new_payload, NEW_LEN, BOOT_BLOCK_MAX, -1, true);
        if (assert_recoverable() == BOOT_REASON_APP_OK) {
            new_ok++;
        } else {
            stayed++;
        }
        points++;
    }
    /* the cuts really land inside the session: some leave the drive in its
     * bootloader (slot erased or half written), some after the marker */
    TEST_ASSERT_TRUE(stayed >= 1u);
    TEST_ASSERT_TRUE(new_ok >= 1u);
    printf("boot: power cut at %u of %ld flash byte operations: %u in bootloader, %u new app, "
           "0 corrupt, %u second flashes ok\n",
           points, total, stayed, new_ok, points);
}

static void test_geometries(void)
{
    static const uint32_t ws[] = {1u, 4u, 16u, 32u};
    static const uint32_t ps[] = {128u, 512u, 1024u, 4096u};
    unsigned i;

    for (i = 0; i < 4u; i++) {
        TEST_ASSERT_TRUE(flash_sim_configure(BASE, SIZE, ps[i], ws[i]));
        cfg.slot_size = SIZE - ps[i];
        TEST_ASSERT_TRUE(boot_init(&boot, &cfg));
        TEST_ASSERT_TRUE(host_flash(new_hdr, new_payload, NEW_LEN, 96u, -1, true));
        TEST_ASSERT_EQUAL(BOOT_REASON_APP_OK, reset_drive());
        TEST_ASSERT_TRUE(boot_app_mark_bad(&cfg));
        TEST_ASSERT_EQUAL(BOOT_REASON_MARKED_BAD, reset_drive());
        TEST_ASSERT_EQUAL_UINT32(0u, flash_sim_stats()->violations);
    }
}

static void test_init_rejects_bad_config(void)
{
    boot_config_t c = cfg;
    c.slot_base = BASE + 8u;
    TEST_ASSERT_FALSE(boot_init(&boot, &c));
    c = cfg;
    c.slot_size = SIZE + PAGE;
    TEST_ASSERT_FALSE(boot_init(&boot, &c));
    c = cfg;
    c.slot_base = BASE - PAGE;
    TEST_ASSERT_FALSE(boot_init(&boot, &c));
    c = cfg;
    c.slot_size = 0u;
    TEST_ASSERT_FALSE(boot_init(&boot, &c));
    TEST_ASSERT_TRUE(flash_sim_configure(BASE, SIZE, PAGE, 64u));
    TEST_ASSERT_FALSE(boot_init(&boot, &cfg));
    boot_config_default(&c, BOARD);
    TEST_ASSERT_EQUAL_HEX32(BASE, c.slot_base);
    TEST_ASSERT_EQUAL_UINT32(0u, c.slot_size); /* 16 KiB region < reserve: unusable */
    TEST_ASSERT_FALSE(boot_init(&boot, &c));
    TEST_ASSERT_TRUE(flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                                         FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE));
    boot_config_default(&c, BOARD);
    TEST_ASSERT_EQUAL_UINT32(FLASH_SIM_DEFAULT_SIZE - BOOT_RESERVED_TOP_DEFAULT, c.slot_size);
    TEST_ASSERT_EQUAL_UINT32(BOOT_WINDOW_US_DEFAULT, c.window_us);
    TEST_ASSERT_TRUE(boot_init(&boot, &c));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_image_roundtrip_and_specific_errors);
    RUN_TEST(test_image_reserved_must_be_zero);
    RUN_TEST(test_erased_flash_stays_in_bootloader);
    RUN_TEST(test_full_flash_then_boot_jumps_to_load_address);
    RUN_TEST(test_connect_reports_layout);
    RUN_TEST(test_identify_in_bootloader_and_unknown_ids);
    RUN_TEST(test_repeated_request_is_answered_from_cache_not_executed);
    RUN_TEST(test_window_then_jump_and_host_connect_cancels_it);
    RUN_TEST(test_host_request_word_is_honoured_once);
    RUN_TEST(test_application_marked_bad_stays);
    RUN_TEST(test_mark_bad_interrupted_still_stays_or_runs_valid);
    RUN_TEST(test_payload_bit_flip_in_flash_is_caught_at_boot);
    RUN_TEST(test_header_or_marker_corruption_is_caught_at_boot);
    RUN_TEST(test_bad_images_refused_before_anything_is_erased);
    RUN_TEST(test_write_rules);
    RUN_TEST(test_finish_with_missing_block_is_refused_and_not_valid);
    RUN_TEST(test_bit_flip_in_transit_detected_by_final_crc);
    RUN_TEST(test_interrupt_at_every_block_boundary);
    RUN_TEST(test_power_cut_at_random_bytes_never_runs_a_corrupt_image);
    RUN_TEST(test_geometries);
    RUN_TEST(test_init_rejects_bad_config);
    return UNITY_END();
}
