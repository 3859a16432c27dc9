/*
 * preempt.h - the tick/main contract's primitives (internal to the core;
 * docs/tick-main.md).
 *
 * Specification
 * -------------
 * The control tick is an interrupt that may preempt the main context
 * (background loop, link handlers) between any two of its instructions;
 * the main context never preempts the tick. Every field shared between the
 * two is written by one context only and says which in its declaration
 * (`tick`, `main`); see docs/tick-main.md.
 *
 * CORE_SHARED   qualifier of a scalar written by one context and read by the
 *               other: volatile on the MCU (every access is one load or
 *               store, in program order with the other volatile accesses);
 *               a C11 atomic in the ThreadSanitizer build (CORE_TSAN, where
 *               the tick is a second thread), so TSan checks the discipline.
 * CORE_BARRIER()  compiler barrier: plain stores before it (a request's
 *               payload) are done before the volatile store after it (the
 *               request flag) that hands them to the other context; the MCU
 *               has one core, so no hardware fence is needed.
 * PREEMPT_POINT()  a place in main-context code where the tick may run:
 *               nothing in a production build; with CORE_PREEMPT_TEST (the
 *               unit-test build) it calls preempt_hook(file, line) when the
 *               hook is set, which tests/unit/test_preempt.c sets to run one
 *               drive_tick() there. The hook is defined by the test build
 *               (tests/unit/support/preempt_hook.c).
 * CORE_NO_TSAN  function attribute for the seqlock readers: their reads of
 *               the tick's state race by design and are validated by the
 *               sequence count (nothing in other builds).
 */
#ifndef PREEMPT_H
#define PREEMPT_H

#if defined(CORE_TSAN)
#define CORE_SHARED  _Atomic
#define CORE_NO_TSAN __attribute__((no_sanitize("thread")))
#else
#define CORE_SHARED volatile
#define CORE_NO_TSAN
#endif

#if defined(__GNUC__)
#define CORE_BARRIER() __asm__ volatile("" ::: "memory")
#else
#define CORE_BARRIER() ((void)0)
#endif

#if defined(CORE_PREEMPT_TEST)
typedef void (*preempt_hook_fn)(const char *file, int line);
extern preempt_hook_fn preempt_hook;
#define PREEMPT_POINT()                                                                            \
    do {                                                                                           \
        if (preempt_hook != 0) {                                                                   \
            preempt_hook(__FILE__, __LINE__);                                                      \
        }                                                                                          \
    } while (0)
#else
#define PREEMPT_POINT() ((void)0)
#endif

#endif /* PREEMPT_H */
