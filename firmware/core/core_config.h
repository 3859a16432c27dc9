/*
 * core_config.h - compile-time sizes of the core (fixed memory, no heap).
 * Override with -D on the compiler command line of a port.
 */
#ifndef CORE_CONFIG_H
#define CORE_CONFIG_H

/* Number of servo axes (X, Y, Z by default; more by configuration). */
#ifndef CORE_AXES
#define CORE_AXES 3
#endif

/* Default control tick rate (Hz); ports and the simulator may choose another. */
#ifndef CORE_TICK_HZ_DEFAULT
#define CORE_TICK_HZ_DEFAULT 10000
#endif

#endif /* CORE_CONFIG_H */
