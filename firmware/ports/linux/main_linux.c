/*
 * main_linux.c - `contour-drive`, the drive application as a Linux process
 * (firmware/ports/linux, hal_linux.h). Usage:
 *
 *   contour-drive [--serial DEV|pty] [--can IFACE] [--gpiochip DEV]
 *                 [--line-base N] [--pwm PATTERN] [--flash FILE] [--axes N]
 *                 [--tick-hz N] [--nm-per-count N] [--node N] [--rt]
 *                 [--ticks N]
 *
 * Serves the protocol on the serial device (or a new pseudo-terminal,
 * "serial: PATH" on stdout) and/or SocketCAN; prints "ready" once running.
 * --ticks N stops after N control ticks (tests); SIGINT / SIGTERM stop it.
 * On exit it prints "ticks T missed M edges E pos P0 P1 .." (counts).
 * Exit status: 0 ok, 2 bad arguments, 1 start-up failure.
 */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "boot/boot.h"
#include "calib.h"
#include "drive.h"
#include "hal.h"
#include "hal_linux.h"
#include "port.h"
#include "proto_msgs.h"

/* (major << 16) | (minor << 8) | patch, set by the build (mk/firmware.sh) */
#ifndef PORT_FW_VERSION
#define PORT_FW_VERSION 0u
#endif

static volatile int stop_flag;

static void on_signal(int sig)
{
    (void)sig;
    stop_flag = 1;
}

static int usage(const char *msg, const char *arg)
{
    fprintf(stderr, "contour-drive: %s%s%s\n", msg, arg ? ": " : "", arg ? arg : "");
    fprintf(stderr, "usage: contour-drive [--serial DEV|pty] [--can IFACE] [--gpiochip DEV] "
                    "[--line-base N] [--pwm PATTERN] [--flash FILE] [--axes N] [--tick-hz N] "
                    "[--nm-per-count N] [--node N] [--rt] [--ticks N]\n");
    return 2;
}

static bool number(const char *s, unsigned long lo, unsigned long hi, unsigned long *out)
{
    char *end;
    unsigned long v;

    if (s == NULL || *s == '\0' || *s == '-') {
        return false;
    }
    v = strtoul(s, &end, 0);
    if (*end != '\0' || v < lo || v > hi) {
        return false;
    }
    *out = v;
    return true;
}

int main(int argc, char **argv)
{
    linux_hal_config_t hc;
    drive_config_t cfg;
    port_app_config_t pc;
    uint32_t lines[CORE_AXES] = {0};
    unsigned long nm_per_count = 1250, node = 1, ticks = 0, v;
    unsigned i;
    int a;

    memset(&hc, 0, sizeof hc);
    hc.axes = 3;
    hc.tick_hz = 1000;
    for (a = 1; a < argc; a++) {
        const char *o = argv[a], *val = a + 1 < argc ? argv[a + 1] : NULL;

        if (strcmp(o, "--rt") == 0) {
            hc.realtime = true;
            continue;
        }
        if (val == NULL) {
            return usage("missing value or unknown option", o);
        }
        a++;
        if (strcmp(o, "--serial") == 0) {
            hc.serial = val;
        } else if (strcmp(o, "--can") == 0) {
            hc.can = val;
        } else if (strcmp(o, "--gpiochip") == 0) {
            hc.gpiochip = val;
        } else if (strcmp(o, "--pwm") == 0) {
            hc.pwm = val;
        } else if (strcmp(o, "--flash") == 0) {
            hc.flash_file = val;
        } else if (strcmp(o, "--line-base") == 0 && number(val, 0, 1023, &v)) {
            hc.line_base = (unsigned)v;
        } else if (strcmp(o, "--axes") == 0 && number(val, 1, CORE_AXES, &v)) {
            hc.axes = (unsigned)v;
        } else if (strcmp(o, "--tick-hz") == 0 && number(val, 100, 20000, &v)) {
            hc.tick_hz = (uint32_t)v;
        } else if (strcmp(o, "--nm-per-count") == 0 && number(val, 1, 1000000, &v)) {
            nm_per_count = v;
        } else if (strcmp(o, "--node") == 0 && number(val, 1, PROTO_CAN_NODE_MAX, &v)) {
            node = v;
        } else if (strcmp(o, "--ticks") == 0 && number(val, 1, 1000000000, &v)) {
            ticks = v;
        } else {
            return usage("bad option or value", o);
        }
    }
    if (hc.serial == NULL && hc.can == NULL) {
        return usage("give --serial and/or --can", NULL);
    }
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    if (!linux_hal_open(&hc, lines)) {
        return 1;
    }
    drive_config_default(&cfg, hc.tick_hz, hc.axes);
    for (i = 0; i < hc.axes; i++) {
        cfg.nm_per_count_num[i] = (int32_t)nm_per_count;
        cfg.nm_per_count_den[i] = 1;
        cfg.enc_initial_lines[i] = lines[i];
        cfg.servo.axis[i].out_max_mv = 10000;
        cfg.servo.axis[i].i_max_mv = 10000;
    }
    cfg.servo.cec.pid.out_max_mv = 10000;
    cfg.servo.cec.pid.i_max_mv = 10000;
    if (drive_init(&cfg) != DRIVE_OK) {
        fprintf(stderr, "contour-drive: the drive refused its configuration\n");
        linux_hal_close();
        return 1;
    }
    calib_init();
    pc.board_id = BOOT_BOARD_LINUX;
    pc.node_id = (uint8_t)node;
    pc.axes = (uint8_t)hc.axes;
    pc.serial = hc.serial != NULL;
    pc.can = hc.can != NULL;
    pc.tick_hz = hc.tick_hz;
    pc.capabilities = 0u;
    pc.fw_version = PORT_FW_VERSION;
    pc.boot = NULL; /* a process: updated by replacing its file, no bootloader */
    if (!port_app_init(&pc)) {
        fprintf(stderr, "contour-drive: protocol refused node %lu / %u axes\n", node, hc.axes);
        linux_hal_close();
        return 1;
    }
    printf("ready\n");
    fflush(stdout);
    linux_run(&stop_flag, ticks);
    printf("ticks %llu missed %llu edges %llu pos", (unsigned long long)linux_ticks(),
           (unsigned long long)linux_missed_ticks(), (unsigned long long)linux_edges());
    for (i = 0; i < hc.axes; i++) {
        printf(" %lld", (long long)drive_encoder_count(i));
    }
    printf("\n");
    fflush(stdout);
    linux_hal_close();
    return 0;
}
