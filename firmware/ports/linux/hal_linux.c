/* hal_linux.c - HAL of the Linux board (see hal_linux.h). */
#include "hal_linux.h"

#include <errno.h>
#include <fcntl.h>
#include <gpiod.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sched.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/timerfd.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include "calib.h"
#include "drive.h"
#include "hal.h"
#include "app.h"
#include "qdec.h"

#define EDGE_BUF 256u
#define MV_FULL  10000

typedef struct {
    linux_hal_config_t cfg;
    uint64_t epoch_ns;
    int tfd;
    /* serial */
    int ser_fd, pty_slave;
    /* CAN */
    int can_fd;
    /* GPIO */
    struct gpiod_chip *chip;
    struct gpiod_line_request *enc_req, *out_req, *in_req;
    struct gpiod_edge_event_buffer *evbuf;
    uint32_t levels[CORE_AXES];
    bool fault[CORE_AXES];
    bool home[CORE_AXES]; /* home switch, read with the faults */
    bool en[CORE_AXES];
    int en_line[CORE_AXES]; /* last EN level written, -1 unknown */
    int dir[CORE_AXES];     /* last DIR level written, -1 unknown */
    int32_t mv[CORE_AXES];
    /* flash */
    uint8_t flash[LINUX_FLASH_SIZE];
    int flash_fd;
    /* counters */
    uint64_t ticks, missed, edges;
} linux_state_t;

static linux_state_t lx;

static uint64_t mono_ns(void)
{
    struct timespec ts;

    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

uint32_t hal_time_us(void)
{
    return (uint32_t)((mono_ns() - lx.epoch_ns) / 1000u);
}

static unsigned line(unsigned axis, unsigned k)
{
    return lx.cfg.line_base + LINUX_LINES_PER_AXIS * axis + k;
}

/* ---- GPIO ---------------------------------------------------------------------- */

static struct gpiod_line_request *request(const unsigned *offs, size_t n,
                                          enum gpiod_line_direction dir, enum gpiod_line_edge edge,
                                          enum gpiod_line_bias bias)
{
    struct gpiod_request_config *rc = gpiod_request_config_new();
    struct gpiod_line_settings *ls = gpiod_line_settings_new();
    struct gpiod_line_config *lc = gpiod_line_config_new();
    struct gpiod_line_request *r = NULL;

    if (rc != NULL && ls != NULL && lc != NULL) {
        gpiod_request_config_set_consumer(rc, "contour-drive");
        if (gpiod_line_settings_set_direction(ls, dir) == 0 &&
            (edge == GPIOD_LINE_EDGE_NONE ||
             gpiod_line_settings_set_edge_detection(ls, edge) == 0) &&
            (bias == GPIOD_LINE_BIAS_AS_IS || gpiod_line_settings_set_bias(ls, bias) == 0) &&
            (dir != GPIOD_LINE_DIRECTION_OUTPUT ||
             gpiod_line_settings_set_output_value(ls, GPIOD_LINE_VALUE_INACTIVE) == 0) &&
            gpiod_line_config_add_line_settings(lc, offs, n, ls) == 0) {
            r = gpiod_chip_request_lines(lx.chip, rc, lc);
        }
    }
    if (lc != NULL) {
        gpiod_line_config_free(lc);
    }
    if (ls != NULL) {
        gpiod_line_settings_free(ls);
    }
    if (rc != NULL) {
        gpiod_request_config_free(rc);
    }
    return r;
}

static bool gpio_open(uint32_t initial[CORE_AXES])
{
    unsigned enc[2 * CORE_AXES], out[2 * CORE_AXES], in[2 * CORE_AXES], i;
    unsigned n = lx.cfg.axes;

    lx.chip = gpiod_chip_open(lx.cfg.gpiochip);
    if (lx.chip == NULL) {
        fprintf(stderr, "contour-drive: cannot open GPIO chip %s: %s\n", lx.cfg.gpiochip,
                strerror(errno));
        return false;
    }
    for (i = 0; i < n; i++) {
        enc[2 * i] = line(i, 0);
        enc[2 * i + 1] = line(i, 1);
        out[2 * i] = line(i, 2);
        out[2 * i + 1] = line(i, 3);
        in[2 * i] = line(i, 4);     /* FAULT */
        in[2 * i + 1] = line(i, 5); /* HOME */
    }
    lx.enc_req = request(enc, 2 * n, GPIOD_LINE_DIRECTION_INPUT, GPIOD_LINE_EDGE_BOTH,
                         GPIOD_LINE_BIAS_AS_IS);
    lx.out_req = request(out, 2 * n, GPIOD_LINE_DIRECTION_OUTPUT, GPIOD_LINE_EDGE_NONE,
                         GPIOD_LINE_BIAS_AS_IS);
    lx.in_req = request(in, 2 * n, GPIOD_LINE_DIRECTION_INPUT, GPIOD_LINE_EDGE_NONE,
                        GPIOD_LINE_BIAS_PULL_UP);
    lx.evbuf = gpiod_edge_event_buffer_new(EDGE_BUF);
    if (lx.enc_req == NULL || lx.out_req == NULL || lx.in_req == NULL || lx.evbuf == NULL) {
        fprintf(stderr, "contour-drive: cannot request GPIO lines %u..%u of %s: %s\n",
                lx.cfg.line_base, line(n - 1u, 5), lx.cfg.gpiochip, strerror(errno));
        return false;
    }
    for (i = 0; i < n; i++) {
        enum gpiod_line_value a = gpiod_line_request_get_value(lx.enc_req, line(i, 0));
        enum gpiod_line_value b = gpiod_line_request_get_value(lx.enc_req, line(i, 1));

        if (a == GPIOD_LINE_VALUE_ERROR || b == GPIOD_LINE_VALUE_ERROR) {
            fprintf(stderr, "contour-drive: cannot read encoder lines of axis %u\n", i);
            return false;
        }
        lx.levels[i] = (a == GPIOD_LINE_VALUE_ACTIVE ? QDEC_LINE_A : 0u) |
                       (b == GPIOD_LINE_VALUE_ACTIVE ? QDEC_LINE_B : 0u);
        initial[i] = lx.levels[i];
        lx.dir[i] = -1;
        lx.en_line[i] = -1;
    }
    return true;
}

/* Deliver every waiting edge event (non-blocking). */
static void gpio_edges(void)
{
    struct pollfd p;

    if (lx.enc_req == NULL) {
        return;
    }
    p.fd = gpiod_line_request_get_fd(lx.enc_req);
    p.events = POLLIN;
    while (poll(&p, 1, 0) > 0 && (p.revents & POLLIN)) {
        int n = gpiod_line_request_read_edge_events(lx.enc_req, lx.evbuf, EDGE_BUF), k;

        if (n <= 0) {
            return;
        }
        for (k = 0; k < n; k++) {
            struct gpiod_edge_event *e = gpiod_edge_event_buffer_get_event(lx.evbuf, (unsigned)k);
            unsigned off = gpiod_edge_event_get_line_offset(e) - lx.cfg.line_base;
            unsigned axis = off / LINUX_LINES_PER_AXIS, which = off % LINUX_LINES_PER_AXIS;
            uint32_t bit = which == 0u ? QDEC_LINE_A : QDEC_LINE_B;
            uint64_t ts = gpiod_edge_event_get_timestamp_ns(e);

            if (axis >= lx.cfg.axes || which > 1u) {
                continue;
            }
            if (gpiod_edge_event_get_event_type(e) == GPIOD_EDGE_EVENT_RISING_EDGE) {
                lx.levels[axis] |= bit;
            } else {
                lx.levels[axis] &= ~bit;
            }
            lx.edges++;
            drive_encoder_edge(axis, lx.levels[axis], (uint32_t)(ts - lx.epoch_ns));
        }
    }
}

static void gpio_faults(void)
{
    unsigned i;

    for (i = 0; lx.in_req != NULL && i < lx.cfg.axes; i++) {
        lx.fault[i] =
            gpiod_line_request_get_value(lx.in_req, line(i, 4)) == GPIOD_LINE_VALUE_INACTIVE;
        lx.home[i] =
            gpiod_line_request_get_value(lx.in_req, line(i, 5)) == GPIOD_LINE_VALUE_INACTIVE;
    }
}

/* ---- motor outputs ----------------------------------------------------------------- */

static void pwm_write(unsigned axis, int32_t mv)
{
    char path[256], val[32];
    int fd, n;

    if (lx.cfg.pwm == NULL) {
        return;
    }
    n = snprintf(path, sizeof path - 16u, lx.cfg.pwm, axis);
    if (n <= 0 || (size_t)n >= sizeof path - 16u) {
        return;
    }
    strcat(path, "/duty_cycle");
    fd = open(path, O_WRONLY);
    if (fd < 0) {
        return;
    }
    /* period 50000 ns (20 kHz) assumed configured; duty in ns */
    n = snprintf(val, sizeof val, "%ld\n", (long)(mv < 0 ? -mv : mv) * 50000L / MV_FULL);
    if (write(fd, val, (size_t)n) < 0) {
        /* a missing PWM channel is not fatal: nothing to do */
    }
    close(fd);
}

void hal_motor_set_mv(unsigned axis, int32_t mv)
{
    int dir;

    if (axis >= lx.cfg.axes) {
        return;
    }
    if (mv > MV_FULL) {
        mv = MV_FULL;
    } else if (mv < -MV_FULL) {
        mv = -MV_FULL;
    }
    if (!lx.en[axis]) {
        mv = 0;
    }
    dir = mv < 0 ? 1 : 0;
    if (dir != lx.dir[axis] && lx.out_req != NULL) {
        gpiod_line_request_set_value(lx.out_req, line(axis, 3),
                                     dir ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE);
        lx.dir[axis] = dir;
    }
    if (mv != lx.mv[axis]) {
        pwm_write(axis, mv);
        lx.mv[axis] = mv;
    }
}

void hal_motor_enable(unsigned axis, bool on)
{
    if (axis >= lx.cfg.axes) {
        return;
    }
    lx.en[axis] = on;
    if (lx.out_req != NULL && lx.en_line[axis] != (int)on) {
        gpiod_line_request_set_value(lx.out_req, line(axis, 2),
                                     on ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE);
        lx.en_line[axis] = (int)on;
    }
    if (!on) {
        hal_motor_set_mv(axis, 0);
    }
}

bool hal_home_switch(unsigned axis)
{
    return axis < lx.cfg.axes && lx.home[axis];
}

bool hal_amp_fault(unsigned axis)
{
    return axis < lx.cfg.axes && lx.fault[axis];
}

void hal_motor_set_mv_all(const int32_t *mv, unsigned n)
{
    hal_generic_set_mv_all(mv, n);
}

uint32_t hal_amp_fault_mask(unsigned n)
{
    return hal_generic_amp_fault_mask(n);
}

bool hal_encoder_counter(unsigned ch, uint32_t *count)
{
    (void)ch;
    (void)count;
    return false; /* edge mode: every A/B change is a GPIO event */
}

bool hal_encoder_mean(unsigned axis, int64_t *lag_q16)
{
    (void)axis;
    (void)lag_q16;
    return false; /* GPIO events carry no time fine enough: enc_mean refused */
}

/* ---- serial ------------------------------------------------------------------------- */

static bool serial_open(void)
{
    struct termios t;

    if (strcmp(lx.cfg.serial, "pty") == 0) {
        const char *name;

        lx.ser_fd = posix_openpt(O_RDWR | O_NOCTTY);
        if (lx.ser_fd < 0 || grantpt(lx.ser_fd) != 0 || unlockpt(lx.ser_fd) != 0 ||
            (name = ptsname(lx.ser_fd)) == NULL) {
            fprintf(stderr, "contour-drive: cannot create a pseudo-terminal: %s\n",
                    strerror(errno));
            return false;
        }
        /* keep the slave open: the host may close and reopen it */
        lx.pty_slave = open(name, O_RDWR | O_NOCTTY);
        if (lx.pty_slave >= 0 && tcgetattr(lx.pty_slave, &t) == 0) {
            cfmakeraw(&t);
            tcsetattr(lx.pty_slave, TCSANOW, &t);
        }
        printf("serial: %s\n", name);
        fflush(stdout);
    } else {
        lx.ser_fd = open(lx.cfg.serial, O_RDWR | O_NOCTTY);
        if (lx.ser_fd < 0) {
            fprintf(stderr, "contour-drive: cannot open %s: %s\n", lx.cfg.serial, strerror(errno));
            return false;
        }
        if (tcgetattr(lx.ser_fd, &t) == 0) {
            cfmakeraw(&t);
            cfsetispeed(&t, B115200);
            cfsetospeed(&t, B115200);
            tcsetattr(lx.ser_fd, TCSANOW, &t);
        }
    }
    return fcntl(lx.ser_fd, F_SETFL, fcntl(lx.ser_fd, F_GETFL) | O_NONBLOCK) == 0;
}

size_t hal_uart_write(const uint8_t *data, size_t len)
{
    ssize_t n;

    if (lx.ser_fd < 0 || data == NULL || len == 0u) {
        return 0;
    }
    n = write(lx.ser_fd, data, len);
    return n > 0 ? (size_t)n : 0u;
}

size_t hal_uart_read(uint8_t *data, size_t cap)
{
    ssize_t n;

    if (lx.ser_fd < 0 || data == NULL || cap == 0u) {
        return 0;
    }
    n = read(lx.ser_fd, data, cap);
    return n > 0 ? (size_t)n : 0u;
}

bool hal_uart_tx_idle(void)
{
    int q = 0;

    return lx.ser_fd < 0 || ioctl(lx.ser_fd, TIOCOUTQ, &q) != 0 || q == 0;
}

/* ---- SocketCAN ------------------------------------------------------------------------- */

static bool can_open(void)
{
    struct sockaddr_can addr;
    struct ifreq ifr;

    lx.can_fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (lx.can_fd < 0) {
        fprintf(stderr, "contour-drive: no SocketCAN in this kernel: %s\n", strerror(errno));
        return false;
    }
    memset(&ifr, 0, sizeof ifr);
    if (strlen(lx.cfg.can) >= sizeof ifr.ifr_name) {
        fprintf(stderr, "contour-drive: CAN interface name too long: %s\n", lx.cfg.can);
        return false;
    }
    strcpy(ifr.ifr_name, lx.cfg.can);
    if (ioctl(lx.can_fd, SIOCGIFINDEX, &ifr) < 0) {
        fprintf(stderr, "contour-drive: no CAN interface %s: %s\n", lx.cfg.can, strerror(errno));
        return false;
    }
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (bind(lx.can_fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        fprintf(stderr, "contour-drive: cannot bind to %s: %s\n", lx.cfg.can, strerror(errno));
        return false;
    }
    return fcntl(lx.can_fd, F_SETFL, fcntl(lx.can_fd, F_GETFL) | O_NONBLOCK) == 0;
}

bool hal_can_send(uint32_t id, const uint8_t *data, uint8_t len)
{
    struct can_frame f;

    if (lx.can_fd < 0 || len > 8u || (len > 0u && data == NULL) ||
        ((id & CAN_EFF_FLAG) ? (id & ~CAN_EFF_FLAG) > CAN_EFF_MASK : id > CAN_SFF_MASK)) {
        return false;
    }
    memset(&f, 0, sizeof f);
    f.can_id = id;
    f.can_dlc = len;
    if (len > 0u) {
        memcpy(f.data, data, len);
    }
    return write(lx.can_fd, &f, sizeof f) == (ssize_t)sizeof f;
}

bool hal_can_receive(uint32_t *id, uint8_t *data, uint8_t *len)
{
    struct can_frame f;

    if (lx.can_fd < 0 || id == NULL || data == NULL || len == NULL) {
        return false;
    }
    for (;;) {
        if (read(lx.can_fd, &f, sizeof f) != (ssize_t)sizeof f) {
            return false;
        }
        if (f.can_id & (CAN_RTR_FLAG | CAN_ERR_FLAG)) {
            continue; /* data frames only */
        }
        /* HAL_CAN_EFF is CAN_EFF_FLAG: the id goes through as it is */
        *id = f.can_id & ((f.can_id & CAN_EFF_FLAG) ? (CAN_EFF_FLAG | CAN_EFF_MASK) : CAN_SFF_MASK);
        *len = f.can_dlc > 8u ? 8u : f.can_dlc;
        memcpy(data, f.data, *len);
        return true;
    }
}

/* ---- flash: a file (or RAM) with NOR rules ---------------------------------------------- */

static const hal_flash_layout_t flash_layout = {LINUX_FLASH_BASE, LINUX_FLASH_SIZE,
                                                LINUX_FLASH_PAGE, LINUX_FLASH_WRITE};

const hal_flash_layout_t *hal_flash_layout(void)
{
    return &flash_layout;
}

static bool in_flash(uint32_t addr, size_t len)
{
    /* LINUX_FLASH_BASE is 0: the unsigned difference covers addr < base too */
    return len <= LINUX_FLASH_SIZE && addr - LINUX_FLASH_BASE <= LINUX_FLASH_SIZE - len;
}

static bool flash_sync(uint32_t off, size_t len)
{
    return lx.flash_fd < 0 || pwrite(lx.flash_fd, lx.flash + off, len, off) == (ssize_t)len;
}

bool hal_flash_erase_page(uint32_t addr)
{
    uint32_t off;

    if (!in_flash(addr, 1u)) {
        return false;
    }
    off = (addr - LINUX_FLASH_BASE) / LINUX_FLASH_PAGE * LINUX_FLASH_PAGE;
    memset(lx.flash + off, 0xFF, LINUX_FLASH_PAGE);
    return flash_sync(off, LINUX_FLASH_PAGE);
}

bool hal_flash_write(uint32_t addr, const uint8_t *data, size_t len)
{
    uint32_t off = addr - LINUX_FLASH_BASE;
    size_t i;

    if (data == NULL || !in_flash(addr, len) || off % LINUX_FLASH_WRITE != 0u ||
        len % LINUX_FLASH_WRITE != 0u) {
        return false;
    }
    for (i = 0; i < len; i++) {
        if (lx.flash[off + i] != 0xFFu) {
            return false;
        }
    }
    memcpy(lx.flash + off, data, len);
    return flash_sync(off, len);
}

bool hal_flash_read(uint32_t addr, uint8_t *data, size_t len)
{
    if (data == NULL || !in_flash(addr, len)) {
        return false;
    }
    memcpy(data, lx.flash + (addr - LINUX_FLASH_BASE), len);
    return true;
}

static bool flash_open(void)
{
    ssize_t n;

    memset(lx.flash, 0xFF, sizeof lx.flash);
    lx.flash_fd = -1;
    if (lx.cfg.flash_file == NULL) {
        return true;
    }
    lx.flash_fd = open(lx.cfg.flash_file, O_RDWR | O_CREAT, 0644);
    if (lx.flash_fd < 0) {
        fprintf(stderr, "contour-drive: cannot open %s: %s\n", lx.cfg.flash_file, strerror(errno));
        return false;
    }
    n = pread(lx.flash_fd, lx.flash, sizeof lx.flash, 0);
    if (n != (ssize_t)sizeof lx.flash) {
        memset(lx.flash, 0xFF, sizeof lx.flash); /* new or short file: erased */
        return flash_sync(0, sizeof lx.flash);
    }
    return true;
}

/* ---- system -------------------------------------------------------------------------------- */

void hal_watchdog_start(void)
{
}

void hal_watchdog_kick(void)
{
    /* the process is supervised by the OS (systemd's WatchdogSec if wanted) */
}

void hal_system_reset(void)
{
    fprintf(stderr, "contour-drive: reset requested: exiting (the service manager restarts)\n");
    linux_hal_close();
    exit(3);
}

bool linux_hal_open(const linux_hal_config_t *cfg, uint32_t initial_lines[CORE_AXES])
{
    struct itimerspec its;
    uint64_t period_ns;

    memset(&lx, 0, offsetof(linux_state_t, flash));
    lx.cfg = *cfg;
    lx.ser_fd = lx.pty_slave = lx.can_fd = lx.tfd = -1;
    lx.epoch_ns = mono_ns();
    if (cfg->axes < 1u || cfg->axes > CORE_AXES || cfg->tick_hz < 100u || cfg->tick_hz > 20000u) {
        fprintf(stderr, "contour-drive: axes 1..%u and tick 100..20000 Hz\n", (unsigned)CORE_AXES);
        return false;
    }
    if (!flash_open() || (cfg->gpiochip != NULL && !gpio_open(initial_lines)) ||
        (cfg->serial != NULL && !serial_open()) || (cfg->can != NULL && !can_open())) {
        return false;
    }
    lx.tfd = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK);
    period_ns = 1000000000u / cfg->tick_hz;
    its.it_interval.tv_sec = 0;
    its.it_interval.tv_nsec = (long)period_ns;
    its.it_value = its.it_interval;
    if (lx.tfd < 0 || timerfd_settime(lx.tfd, 0, &its, NULL) != 0) {
        fprintf(stderr, "contour-drive: timerfd: %s\n", strerror(errno));
        return false;
    }
    if (cfg->realtime) {
        struct sched_param sp;

        sp.sched_priority = 50;
        if (sched_setscheduler(0, SCHED_FIFO, &sp) != 0) {
            fprintf(stderr, "contour-drive: no real-time scheduling (%s): running as normal\n",
                    strerror(errno));
        }
    }
    return true;
}

void linux_hal_close(void)
{
    if (lx.enc_req != NULL) {
        gpiod_line_request_release(lx.enc_req);
    }
    if (lx.out_req != NULL) {
        gpiod_line_request_release(lx.out_req);
    }
    if (lx.in_req != NULL) {
        gpiod_line_request_release(lx.in_req);
    }
    if (lx.evbuf != NULL) {
        gpiod_edge_event_buffer_free(lx.evbuf);
    }
    if (lx.chip != NULL) {
        gpiod_chip_close(lx.chip);
    }
    lx.enc_req = lx.out_req = lx.in_req = NULL;
    lx.evbuf = NULL;
    lx.chip = NULL;
    if (lx.flash_fd >= 0) {
        close(lx.flash_fd);
        lx.flash_fd = -1;
    }
}

void linux_run(volatile int *stop, uint64_t max_ticks)
{
    while (!*stop && (max_ticks == 0u || lx.ticks < max_ticks)) {
        struct pollfd p[4];
        nfds_t n = 0;
        uint64_t exp;

        p[n].fd = lx.tfd;
        p[n++].events = POLLIN;
        if (lx.enc_req != NULL) {
            p[n].fd = gpiod_line_request_get_fd(lx.enc_req);
            p[n++].events = POLLIN;
        }
        if (lx.ser_fd >= 0) {
            p[n].fd = lx.ser_fd;
            p[n++].events = POLLIN;
        }
        if (lx.can_fd >= 0) {
            p[n].fd = lx.can_fd;
            p[n++].events = POLLIN;
        }
        if (poll(p, n, 100) < 0 && errno != EINTR) {
            break;
        }
        gpio_edges();
        if (read(lx.tfd, &exp, sizeof exp) == (ssize_t)sizeof exp && exp > 0u) {
            lx.missed += exp - 1u;
            gpio_faults();
            app_tick();
            lx.ticks++;
        }
        app_poll();
    }
}

uint64_t linux_ticks(void)
{
    return lx.ticks;
}

uint64_t linux_missed_ticks(void)
{
    return lx.missed;
}

uint64_t linux_edges(void)
{
    return lx.edges;
}
