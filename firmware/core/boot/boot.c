/* boot.c - see boot.h. */
#include "boot/boot.h"

#include "crc.h"
#include "hal.h"
#include "proto_msgs.h"
#include "proto_reply.h"

#define CHUNK 64u

static uint32_t load_addr_of(const boot_config_t *cfg)
{
    return cfg->slot_base + BOOT_IMAGE_HDR_AREA;
}

static uint32_t max_length_of(const boot_config_t *cfg)
{
    return cfg->slot_size > BOOT_IMAGE_HDR_AREA ? cfg->slot_size - BOOT_IMAGE_HDR_AREA : 0u;
}

static bool all_erased(const uint8_t *p, size_t n)
{
    size_t i;

    for (i = 0; i < n; i++) {
        if (p[i] != 0xFFu) {
            return false;
        }
    }
    return true;
}

static bool same(const uint8_t *a, const uint8_t *b, size_t n)
{
    size_t i;

    for (i = 0; i < n; i++) {
        if (a[i] != b[i]) {
            return false;
        }
    }
    return true;
}

/* CRC-32 of flash [addr, addr + len). */
static bool flash_crc(uint32_t addr, uint32_t len, uint32_t *crc)
{
    uint8_t buf[CHUNK];
    uint32_t c = CRC32_INIT;

    while (len > 0u) {
        uint32_t n = len < CHUNK ? len : CHUNK;
        if (!hal_flash_read(addr, buf, n)) {
            return false;
        }
        c = crc32_update(c, buf, n);
        addr += n;
        len -= n;
    }
    *crc = c;
    return true;
}

/* Compare flash [addr, addr + len) with data. */
static bool flash_equals(uint32_t addr, const uint8_t *data, size_t len, bool *eq)
{
    uint8_t buf[CHUNK];

    *eq = true;
    while (len > 0u) {
        size_t n = len < CHUNK ? len : CHUNK;
        if (!hal_flash_read(addr, buf, n)) {
            return false;
        }
        if (!same(buf, data, n)) {
            *eq = false;
        }
        addr += (uint32_t)n;
        data += n;
        len -= n;
    }
    return true;
}

static uint32_t write_size_now(void)
{
    const hal_flash_layout_t *l = hal_flash_layout();
    return l != NULL ? l->write_size : 0u;
}

/* Marker cell content: {magic, header_crc} then erased bytes up to the write
 * unit. Returns the number of bytes to program (max(8, write unit)). */
static size_t marker_make(uint8_t cell[BOOT_MAX_WRITE_SIZE], uint32_t magic, uint32_t hcrc,
                          uint32_t ws)
{
    size_t i;
    size_t n = ws > BOOT_MARK_LEN ? ws : BOOT_MARK_LEN;

    for (i = 0; i < BOOT_MAX_WRITE_SIZE; i++) {
        cell[i] = 0xFFu;
    }
    boot_image_put_u32(cell, magic);
    boot_image_put_u32(cell + 4, hcrc);
    return n;
}

/* Program `len` bytes at addr that must currently be erased or already equal;
 * then verify. Nothing is programmed when any byte conflicts. */
static boot_status_t program_checked(uint32_t addr, const uint8_t *data, size_t len)
{
    bool eq;
    uint8_t cur[CHUNK];
    size_t off = 0;
    bool erased = true;

    if (!flash_equals(addr, data, len, &eq)) {
        return BOOT_ERR_FLASH;
    }
    if (eq) {
        return BOOT_OK;
    }
    while (off < len) {
        size_t n = len - off < CHUNK ? len - off : CHUNK;
        if (!hal_flash_read(addr + (uint32_t)off, cur, n)) {
            return BOOT_ERR_FLASH;
        }
        if (!all_erased(cur, n)) {
            erased = false;
        }
        off += n;
    }
    if (!erased) {
        return BOOT_ERR_NOT_ERASED;
    }
    if (!hal_flash_write(addr, data, len)) {
        return BOOT_ERR_FLASH;
    }
    if (!flash_equals(addr, data, len, &eq)) {
        return BOOT_ERR_FLASH;
    }
    return eq ? BOOT_OK : BOOT_ERR_VERIFY;
}

void boot_config_default(boot_config_t *cfg, uint32_t board_id)
{
    const hal_flash_layout_t *l = hal_flash_layout();
    uint32_t reserve = 0u;

    cfg->board_id = board_id;
    cfg->slot_base = 0u;
    cfg->slot_size = 0u;
    cfg->window_us = BOOT_WINDOW_US_DEFAULT;
    cfg->request_word = NULL;
    cfg->jump = NULL;
    cfg->reset = NULL;
    cfg->ctx = NULL;
    if (l == NULL || l->page_size == 0u) {
        return;
    }
    reserve = (BOOT_RESERVED_TOP_DEFAULT + l->page_size - 1u) / l->page_size * l->page_size;
    cfg->slot_base = l->base;
    cfg->slot_size = l->size > reserve ? l->size - reserve : 0u;
}

bool boot_init(boot_t *b, const boot_config_t *cfg)
{
    const hal_flash_layout_t *l = hal_flash_layout();
    uint32_t ws;
    uint32_t ps;

    b->cfg = *cfg;
    b->mode = BOOT_MODE_STAY;
    b->reason = BOOT_REASON_NO_APP;
    b->session = BOOT_SESSION_IDLE;
    b->reboot_pending = false;
    b->window_start_us = 0u;
    b->hb_sent = false;
    b->hb_last_us = 0u;
    proto_replay_reset(&b->replay);
    b->link_sessions = 0u;
    b->page_size = 0u;
    b->write_size = 0u;
    if (l == NULL) {
        return false;
    }
    ws = l->write_size;
    ps = l->page_size;
    if (ws == 0u || ws > BOOT_MAX_WRITE_SIZE || (ws & (ws - 1u)) != 0u || ps == 0u ||
        ps % ws != 0u) {
        return false;
    }
    if (cfg->slot_base < l->base || cfg->slot_base - l->base > l->size ||
        cfg->slot_size > l->size - (cfg->slot_base - l->base)) {
        return false;
    }
    if ((cfg->slot_base - l->base) % ps != 0u || cfg->slot_size % ps != 0u ||
        cfg->slot_size <= BOOT_IMAGE_HDR_AREA) {
        return false;
    }
    b->page_size = ps;
    b->write_size = ws;
    return true;
}

boot_reason_t boot_check_app(const boot_config_t *cfg, boot_image_header_t *h)
{
    uint8_t raw[BOOT_IMAGE_HDR_SIZE];
    uint8_t mark[BOOT_MARK_LEN];
    boot_image_header_t tmp;
    boot_image_status_t st;
    uint32_t crc;
    unsigned i;

    if (h == NULL) {
        h = &tmp;
    }
    for (i = 0; i < sizeof *h; i++) {
        ((uint8_t *)h)[i] = 0u;
    }
    if (!hal_flash_read(cfg->slot_base, raw, sizeof raw)) {
        return BOOT_REASON_FLASH;
    }
    st = boot_image_parse(raw, h);
    if (st == BOOT_IMAGE_OK) {
        st = boot_image_check(h, cfg->board_id, load_addr_of(cfg), max_length_of(cfg));
    }
    if (st != BOOT_IMAGE_OK) {
        for (i = 0; i < sizeof *h; i++) {
            ((uint8_t *)h)[i] = 0u;
        }
        return st == BOOT_IMAGE_ERR_MAGIC ? BOOT_REASON_NO_APP : BOOT_REASON_BAD_HEADER;
    }
    if (!hal_flash_read(cfg->slot_base + BOOT_MARK_VALID_OFF, mark, sizeof mark)) {
        return BOOT_REASON_FLASH;
    }
    if (boot_image_get_u32(mark) != BOOT_MARK_VALID ||
        boot_image_get_u32(mark + 4) != h->header_crc) {
        return BOOT_REASON_NOT_VALIDATED;
    }
    if (!hal_flash_read(cfg->slot_base + BOOT_MARK_BAD_OFF, mark, sizeof mark)) {
        return BOOT_REASON_FLASH;
    }
    if (!all_erased(mark, sizeof mark)) {
        return BOOT_REASON_MARKED_BAD;
    }
    if (!flash_crc(load_addr_of(cfg), h->length, &crc)) {
        return BOOT_REASON_FLASH;
    }
    if (crc != h->payload_crc) {
        return BOOT_REASON_CRC;
    }
    return BOOT_REASON_APP_OK;
}

static void do_jump(boot_t *b)
{
    b->mode = BOOT_MODE_JUMPED;
    if (b->cfg.jump != NULL) {
        b->cfg.jump(load_addr_of(&b->cfg), b->cfg.ctx);
    }
}

boot_reason_t boot_start(boot_t *b, uint32_t now_us)
{
    bool requested = false;

    b->session = BOOT_SESSION_IDLE;
    b->reboot_pending = false;
    proto_replay_reset(&b->replay);
    if (b->cfg.request_word != NULL) {
        requested = *b->cfg.request_word == BOOT_REQUEST_MAGIC;
        *b->cfg.request_word = 0u;
    }
    if (b->page_size == 0u) {
        b->reason = BOOT_REASON_FLASH;
    } else if (requested) {
        b->reason = BOOT_REASON_REQUESTED;
    } else {
        b->reason = boot_check_app(&b->cfg, NULL);
    }
    b->window_start_us = now_us;
    if (b->reason != BOOT_REASON_APP_OK) {
        b->mode = BOOT_MODE_STAY;
    } else if (b->cfg.window_us == 0u) {
        do_jump(b);
    } else {
        b->mode = BOOT_MODE_WINDOW;
    }
    return b->reason;
}

boot_action_t boot_poll(boot_t *b, uint32_t now_us)
{
    if (b->reboot_pending) {
        b->reboot_pending = false;
        if (b->cfg.reset != NULL) {
            b->cfg.reset(b->cfg.ctx);
        }
        return BOOT_ACT_RESET;
    }
    if (b->mode == BOOT_MODE_WINDOW &&
        (uint32_t)(now_us - b->window_start_us) >= b->cfg.window_us) {
        do_jump(b);
        return BOOT_ACT_JUMP;
    }
    return BOOT_ACT_NONE;
}

/* Any host command keeps the drive in the bootloader. */
static void host_seen(boot_t *b)
{
    if (b->mode == BOOT_MODE_WINDOW) {
        b->mode = BOOT_MODE_STAY;
    }
}

void boot_identify(boot_t *b, boot_ident_t *id)
{
    boot_image_header_t h;
    unsigned i;

    host_seen(b);
    id->boot_version = BOOT_VERSION;
    id->board_id = b->cfg.board_id;
    id->slot_base = b->cfg.slot_base;
    id->slot_size = b->cfg.slot_size;
    id->page_size = b->page_size;
    id->write_size = b->write_size;
    id->load_addr = load_addr_of(&b->cfg);
    id->max_length = max_length_of(&b->cfg);
    id->block_max = BOOT_BLOCK_MAX;
    id->reason = (uint8_t)boot_check_app(&b->cfg, &h);
    id->session = (uint8_t)b->session;
    id->app_version = h.fw_version;
    id->app_length = h.length;
    id->app_crc = h.payload_crc;
    for (i = 0; i < sizeof id->app_build_id; i++) {
        id->app_build_id[i] = h.build_id[i];
    }
}

boot_status_t boot_erase(boot_t *b, const uint8_t hdr[BOOT_IMAGE_HDR_SIZE], uint16_t *pages)
{
    boot_image_header_t h;
    boot_image_status_t st;
    uint32_t end;
    uint32_t n;
    uint32_t i;

    host_seen(b);
    *pages = 0u;
    if (b->page_size == 0u) {
        return BOOT_ERR_FLASH;
    }
    st = boot_image_parse(hdr, &h);
    if (st == BOOT_IMAGE_OK) {
        st = boot_image_check(&h, b->cfg.board_id, load_addr_of(&b->cfg), max_length_of(&b->cfg));
    }
    if (st != BOOT_IMAGE_OK) {
        return (boot_status_t)st;
    }
    /* From here on the old image is gone: header page first. */
    b->session = BOOT_SESSION_IDLE;
    end = BOOT_IMAGE_HDR_AREA + h.length;
    n = (end + b->page_size - 1u) / b->page_size;
    for (i = 0; i < n; i++) {
        if (!hal_flash_erase_page(b->cfg.slot_base + i * b->page_size)) {
            return BOOT_ERR_FLASH;
        }
        *pages = (uint16_t)(i + 1u);
    }
    b->hdr = h;
    for (i = 0; i < BOOT_IMAGE_HDR_SIZE; i++) {
        b->hdr_raw[i] = hdr[i];
    }
    b->session = BOOT_SESSION_WRITING;
    return BOOT_OK;
}

boot_status_t boot_write(boot_t *b, uint32_t addr, const uint8_t *data, size_t len)
{
    uint32_t load = load_addr_of(&b->cfg);
    uint32_t end;
    uint32_t ws = b->write_size;
    size_t full;
    boot_status_t st;

    host_seen(b);
    if (b->session != BOOT_SESSION_WRITING) {
        return BOOT_ERR_STATE;
    }
    if (len == 0u || len > BOOT_BLOCK_MAX) {
        return BOOT_ERR_MALFORMED;
    }
    end = load + b->hdr.length;
    if (addr < load || addr > end || len > end - addr) {
        return BOOT_ERR_RANGE;
    }
    if ((addr - load) % ws != 0u || (len % ws != 0u && addr + len != end)) {
        return BOOT_ERR_ALIGN;
    }
    full = len - len % ws;
    if (full > 0u) {
        st = program_checked(addr, data, full);
        if (st != BOOT_OK) {
            return st;
        }
    }
    if (full < len) {
        /* Last, short block: pad the final write unit with erased bytes. */
        uint8_t unit[BOOT_MAX_WRITE_SIZE];
        size_t i;
        for (i = 0; i < ws; i++) {
            unit[i] = i < len - full ? data[full + i] : 0xFFu;
        }
        st = program_checked(addr + (uint32_t)full, unit, ws);
        if (st != BOOT_OK) {
            return st;
        }
    }
    return BOOT_OK;
}

static bool in_slot(const boot_t *b, uint32_t addr, uint32_t len)
{
    return addr >= b->cfg.slot_base && addr - b->cfg.slot_base <= b->cfg.slot_size &&
           len <= b->cfg.slot_size - (addr - b->cfg.slot_base);
}

boot_status_t boot_read(boot_t *b, uint32_t addr, uint8_t *out, size_t len)
{
    host_seen(b);
    if (len == 0u || len > BOOT_BLOCK_MAX) {
        return BOOT_ERR_MALFORMED;
    }
    if (!in_slot(b, addr, (uint32_t)len)) {
        return BOOT_ERR_RANGE;
    }
    return hal_flash_read(addr, out, len) ? BOOT_OK : BOOT_ERR_FLASH;
}

boot_status_t boot_crc(boot_t *b, uint32_t addr, uint32_t len, uint32_t *crc)
{
    host_seen(b);
    *crc = 0u;
    if (!in_slot(b, addr, len)) {
        return BOOT_ERR_RANGE;
    }
    return flash_crc(addr, len, crc) ? BOOT_OK : BOOT_ERR_FLASH;
}

boot_status_t boot_finish(boot_t *b, uint32_t *crc)
{
    uint8_t cell[BOOT_MAX_WRITE_SIZE];
    size_t n;
    boot_status_t st;

    host_seen(b);
    *crc = 0u;
    if (b->session == BOOT_SESSION_DONE) {
        *crc = b->hdr.payload_crc;
        return BOOT_OK;
    }
    if (b->session != BOOT_SESSION_WRITING) {
        return BOOT_ERR_STATE;
    }
    if (!flash_crc(load_addr_of(&b->cfg), b->hdr.length, crc)) {
        return BOOT_ERR_FLASH;
    }
    if (*crc != b->hdr.payload_crc) {
        return (boot_status_t)BOOT_IMAGE_ERR_PAYLOAD_CRC;
    }
    st = program_checked(b->cfg.slot_base, b->hdr_raw, BOOT_IMAGE_HDR_SIZE);
    if (st != BOOT_OK) {
        return st;
    }
    n = marker_make(cell, BOOT_MARK_VALID, b->hdr.header_crc, b->write_size);
    st = program_checked(b->cfg.slot_base + BOOT_MARK_VALID_OFF, cell, n);
    if (st != BOOT_OK) {
        return st;
    }
    if (boot_check_app(&b->cfg, NULL) != BOOT_REASON_APP_OK) {
        return BOOT_ERR_VERIFY;
    }
    b->session = BOOT_SESSION_DONE;
    b->reason = BOOT_REASON_APP_OK;
    return BOOT_OK;
}

boot_status_t boot_reboot(boot_t *b)
{
    host_seen(b);
    b->reboot_pending = true;
    return BOOT_OK;
}

/* Reply helpers: out = id | seq | payload. */
static size_t reply_boot(uint8_t *out, uint8_t seq, uint8_t req, boot_status_t st, int64_t lo)
{
    return proto_reply_error(out, seq, req, (uint8_t)PROTO_ERROR_CODE_BOOT, (uint16_t)st, lo, 0);
}

static size_t reply_head(uint8_t *out, uint8_t id, uint8_t seq)
{
    out[0] = id;
    out[1] = seq;
    return PROTO_MSG_HDR;
}

static size_t dispatch(boot_t *b, uint8_t id, uint8_t seq, const uint8_t *p, size_t n, uint8_t *out)
{
    uint8_t *o = out + PROTO_MSG_HDR;
    const size_t ocap = BOOT_REPLY_MAX - PROTO_MSG_HDR;
    boot_status_t st;

    switch (id) {
    case PROTO_MSG_SESSION_OPEN: {
        proto_session_open_t so = {0};
        proto_session_reply_t r;
        /* any host version (protocol 1 had no version field): the
         * bootloader is the way back to a matching application */
        if (n == 4u) {
            so.nonce =
                (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
        } else if (!proto_session_open_decode(p, n, &so)) {
            break;
        }
        proto_replay_reset(&b->replay);
        b->link_sessions++;
        r.nonce = so.nonce;
        r.sessions = b->link_sessions;
        r.protocol_version = PROTO_VERSION;
        return reply_head(out, PROTO_MSG_SESSION_REPLY, seq) +
               proto_session_reply_encode(&r, o, ocap);
    }
    case PROTO_MSG_IDENTIFY: {
        proto_identify_reply_t r;
        if (n != PROTO_IDENTIFY_LEN) {
            break;
        }
        r.fw_version = BOOT_VERSION;
        r.build_id = 0u;
        r.protocol_version = PROTO_VERSION;
        r.axes = 0u;
        r.node_id = b->cfg.node_id;
        r.capabilities = 1u << PROTO_CAPABILITY_BOOTLOADER;
        r.tick_hz = 0u;
        r.planner_slots = 0u;
        r.max_payload = PROTO_MAX_PAYLOAD;
        r.board_id = (uint16_t)b->cfg.board_id;
        return reply_head(out, PROTO_MSG_IDENTIFY_REPLY, seq) +
               proto_identify_reply_encode(&r, o, ocap);
    }
    case PROTO_MSG_BOOT_CONNECT: {
        proto_boot_info_t r;
        boot_ident_t id_;
        unsigned i;
        if (n != PROTO_BOOT_CONNECT_LEN) {
            break;
        }
        boot_identify(b, &id_);
        r.boot_version = id_.boot_version;
        r.board_id = id_.board_id;
        r.slot_base = id_.slot_base;
        r.slot_size = id_.slot_size;
        r.page_size = id_.page_size;
        r.write_size = id_.write_size;
        r.load_addr = id_.load_addr;
        r.max_length = id_.max_length;
        r.block_max = id_.block_max;
        r.app_state = id_.reason;
        r.session = id_.session;
        r.app_version = id_.app_version;
        r.app_length = id_.app_length;
        r.app_crc = id_.app_crc;
        for (i = 0; i < sizeof r.app_build_id; i++) {
            r.app_build_id[i] = id_.app_build_id[i];
        }
        return reply_head(out, PROTO_MSG_BOOT_INFO, seq) + proto_boot_info_encode(&r, o, ocap);
    }
    case PROTO_MSG_BOOT_ERASE: {
        proto_boot_erase_t m;
        proto_boot_erased_t r;
        if (!proto_boot_erase_decode(p, n, &m)) {
            break;
        }
        st = boot_erase(b, m.header, &r.pages);
        if (st != BOOT_OK) {
            return reply_boot(out, seq, id, st, 0);
        }
        return reply_head(out, PROTO_MSG_BOOT_ERASED, seq) + proto_boot_erased_encode(&r, o, ocap);
    }
    case PROTO_MSG_BOOT_WRITE: {
        proto_boot_write_t m;
        proto_boot_written_t r;
        if (!proto_boot_write_decode(p, n, &m)) {
            break;
        }
        st = boot_write(b, m.addr, m.data, m.data_len);
        if (st != BOOT_OK) {
            return reply_boot(out, seq, id, st, (int64_t)m.addr);
        }
        r.addr = m.addr;
        r.len = m.data_len;
        return reply_head(out, PROTO_MSG_BOOT_WRITTEN, seq) +
               proto_boot_written_encode(&r, o, ocap);
    }
    case PROTO_MSG_BOOT_READ: {
        proto_boot_read_t m;
        proto_boot_data_t r;
        if (!proto_boot_read_decode(p, n, &m)) {
            break;
        }
        st = m.len <= sizeof r.data ? boot_read(b, m.addr, r.data, m.len) : BOOT_ERR_MALFORMED;
        if (st != BOOT_OK) {
            return reply_boot(out, seq, id, st, (int64_t)m.addr);
        }
        r.addr = m.addr;
        r.data_len = m.len;
        return reply_head(out, PROTO_MSG_BOOT_DATA, seq) + proto_boot_data_encode(&r, o, ocap);
    }
    case PROTO_MSG_BOOT_CRC: {
        proto_boot_crc_t m;
        proto_boot_crc_value_t r;
        if (!proto_boot_crc_decode(p, n, &m)) {
            break;
        }
        st = boot_crc(b, m.addr, m.len, &r.crc);
        if (st != BOOT_OK) {
            return reply_boot(out, seq, id, st, (int64_t)m.addr);
        }
        r.addr = m.addr;
        r.len = m.len;
        return reply_head(out, PROTO_MSG_BOOT_CRC_VALUE, seq) +
               proto_boot_crc_value_encode(&r, o, ocap);
    }
    case PROTO_MSG_BOOT_FINISH: {
        proto_boot_finished_t r;
        if (n != PROTO_BOOT_FINISH_LEN) {
            break;
        }
        st = boot_finish(b, &r.crc);
        if (st != BOOT_OK) {
            return reply_boot(out, seq, id, st, (int64_t)r.crc);
        }
        return reply_head(out, PROTO_MSG_BOOT_FINISHED, seq) +
               proto_boot_finished_encode(&r, o, ocap);
    }
    case PROTO_MSG_BOOT_REBOOT: {
        if (n != PROTO_BOOT_REBOOT_LEN) {
            break;
        }
        (void)boot_reboot(b);
        return proto_reply_ack(out, seq, id);
    }
    default:
        if (id >= 0x80u && id <= 0x8Fu) {
            host_seen(b);
        }
        return proto_reply_error(out, seq, id, (uint8_t)PROTO_ERROR_CODE_UNKNOWN_MESSAGE, 0u, 0, 0);
    }
    return proto_reply_error(out, seq, id, (uint8_t)PROTO_ERROR_CODE_BAD_LENGTH, 0u, 0, 0);
}

/* One request (proto_replay_exec_t; ctx is the boot_t). */
static size_t execute(void *ctx, const uint8_t *msg, size_t len, uint8_t *out)
{
    return dispatch(ctx, msg[0], msg[1], msg + PROTO_MSG_HDR, len - PROTO_MSG_HDR, out);
}

size_t boot_handle(boot_t *b, const uint8_t *msg, size_t len, uint8_t *out, size_t cap)
{
    const proto_msg_info_t *info;

    if (msg == NULL || out == NULL || len < PROTO_MSG_HDR || len > PROTO_MSG_MAX ||
        cap < BOOT_REPLY_MAX) {
        return 0;
    }
    info = proto_msg_info(msg[0]);
    if (info != NULL && info->dir == PROTO_DIR_D2H) {
        return 0; /* a reply or cyclic frame echoed back: never answer it */
    }
    return proto_replay_answer(&b->replay, msg, len, out, cap, execute, b);
}

bool boot_heartbeat(boot_t *b, uint32_t now_us, uint8_t out[8])
{
    proto_heartbeat_t h;

    if (b->hb_sent && (uint32_t)(now_us - b->hb_last_us) < BOOT_HEARTBEAT_MS * 1000u) {
        return false;
    }
    b->hb_sent = true;
    b->hb_last_us = now_us;
    h.state = (uint8_t)PROTO_STATE_BOOTLOADER;
    h.axes = 0u;
    h.protocol_version = PROTO_VERSION;
    h.fw_version = BOOT_VERSION;
    return proto_heartbeat_encode(&h, out, 8u) == 8u;
}

void boot_request_enter(const boot_config_t *cfg)
{
    if (cfg->request_word != NULL) {
        *cfg->request_word = BOOT_REQUEST_MAGIC;
    }
}

bool boot_app_mark_bad(const boot_config_t *cfg)
{
    uint8_t raw[BOOT_IMAGE_HDR_SIZE];
    uint8_t cell[BOOT_MAX_WRITE_SIZE];
    boot_image_header_t h;
    uint32_t ws = write_size_now();
    size_t n;

    if (ws == 0u || ws > BOOT_MAX_WRITE_SIZE) {
        return false;
    }
    if (!hal_flash_read(cfg->slot_base, raw, sizeof raw) ||
        boot_image_parse(raw, &h) != BOOT_IMAGE_OK) {
        return false;
    }
    n = marker_make(cell, BOOT_MARK_BAD, h.header_crc, ws);
    return program_checked(cfg->slot_base + BOOT_MARK_BAD_OFF, cell, n) == BOOT_OK;
}
