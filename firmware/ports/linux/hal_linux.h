/*
 * hal_linux.h - the drive as a Linux process on a single-board computer
 * (firmware/ports/linux): hal.h implemented with libgpiod v2 (encoder lines,
 * enable / direction outputs, fault inputs), SocketCAN raw sockets, a serial
 * device (or a pseudo-terminal), CLOCK_MONOTONIC and a file as flash.
 *
 * GPIO lines on one chip, per axis i (offsets from cfg.line_base + 8 i):
 *   +0 A, +1 B    encoder inputs, both edges, kernel time stamps
 *   +2 EN         amplifier enable output (active high)
 *   +3 DIR        sign of the motor command (high = negative)
 *   +4 FAULT      amplifier fault input, pull-up, low = fault
 *   +5 HOME       home switch input, pull-up, low = on the switch
 *                 (hal_home_switch; read with FAULT before each tick)
 * The command's magnitude goes to an optional sysfs PWM channel per axis
 * (cfg.pwm: printf pattern with the axis, e.g.
 * /sys/class/pwm/pwmchip0/pwm%u; duty 0..100 % = 0..10 V).
 *
 * Everything runs in ONE thread (linux_run): poll() on the tick timerfd, the
 * GPIO edge-event fd, the serial fd and the CAN socket. Edge events are
 * delivered (drive_encoder_edge) as they arrive and always before a tick,
 * so edge and tick context never overlap; the tick runs app_tick(), the
 * rest of each iteration app_poll() (main context). SCHED_FIFO is
 * requested when cfg.realtime is set and the process may (else a warning).
 */
#ifndef HAL_LINUX_H
#define HAL_LINUX_H

#include <stdbool.h>
#include <stdint.h>

#include "core_config.h"

#define LINUX_FLASH_BASE     0x00000000u
#define LINUX_FLASH_SIZE     (256u * 1024u)
#define LINUX_FLASH_PAGE     4096u
#define LINUX_FLASH_WRITE    8u
#define LINUX_LINES_PER_AXIS 8u

typedef struct {
    const char *serial;     /* device path, "pty", or NULL (no serial link) */
    const char *can;        /* SocketCAN interface name, or NULL            */
    const char *gpiochip;   /* e.g. /dev/gpiochip0, or NULL (no GPIO)       */
    unsigned line_base;     /* first line offset                            */
    const char *pwm;        /* sysfs PWM pattern, or NULL                   */
    const char *flash_file; /* parameter store file, or NULL (RAM)          */
    unsigned axes;          /* 1..CORE_AXES                                 */
    uint32_t tick_hz;
    bool realtime;
} linux_hal_config_t;

/* Open everything; fills the initial encoder line levels. Prints
 * "serial: PATH" for a pseudo-terminal. False (message on stderr) on error. */
bool linux_hal_open(const linux_hal_config_t *cfg, uint32_t initial_lines[CORE_AXES]);
void linux_hal_close(void);

/* The event loop; returns when *stop becomes true (signal handler) or
 * after max_ticks ticks (0: no limit). */
void linux_run(volatile int *stop, uint64_t max_ticks);

/* Counters: ticks run, timer expirations missed, edge events delivered. */
uint64_t linux_ticks(void);
uint64_t linux_missed_ticks(void);
uint64_t linux_edges(void);

#endif /* HAL_LINUX_H */
