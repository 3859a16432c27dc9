/*
 * preempt_hook.c - the hook PREEMPT_POINT() calls in the unit-test build
 * (preempt.h): NULL unless a test (test_preempt.c) sets it.
 */
#include "preempt.h"

preempt_hook_fn preempt_hook;
