/*
 * test_tsan_drive.c - the tick/main contract under ThreadSanitizer
 * (docs/tick-main.md; make test-tsan).
 *
 * The firmware core is built with CORE_TSAN (CORE_SHARED fields are C11
 * atomics, the seqlock readers are not instrumented) and -fsanitize=thread.
 * A second thread runs drive_tick() back to back with random pauses, as the
 * tick interrupt would preempt the main context at any instruction (a
 * thread is stricter: main also runs during a tick; see docs/tick-main.md);
 * the axes follow the reference exactly (counter inputs set from the last
 * tick's reference). The main thread runs calib_poll() + drive_poll() and,
 * for ROUNDS rounds chosen by a fixed seed: enable (and queue at once,
 * before the tick applied it), queue 1..3 short lines, then let the job
 * finish, or stop, disable or e-stop it after a random number of polls. Checked after each
 * round (waits are bounded in ticks, never in wall-clock time):
 *   - a job left alone ends IDLE with every block done, at its end point;
 *   - a stopped job ends IDLE (never stuck in STOPPING or RUNNING), with
 *     between 0 and all of its blocks done, and a new block from the stop
 *     point runs to its end;
 *   - disable ends DISABLED, e-stop FAULT, fault_reset DISABLED;
 *   - every third round first runs a job of BATCH_BLOCKS lines sent as
 *     queue_batch messages through the dispatcher (proto_dispatch_handle;
 *     the main loop also runs proto_dispatch_poll, which pumps the intake
 *     ring): it ends IDLE with every block done, at its end point;
 *   - no fault other than the e-stop's, and TSan reports no data race
 *     (halt_on_error: the run fails on the first report).
 */
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib.h"
#include "drive.h"
#include "drive_test.h"
#include "hal_flash_sim.h"
#include "hal_sim.h"
#include "proto_batch.h"
#include "proto_dispatch.h"

#define AXES         3u
#define TICK_HZ      10000u
#define ROUNDS       120u
#define WAIT_TICKS   400000u  /* bound of every wait, in ticks (40 s simulated) */
#define FEED         50000000 /* 50 mm/s */
#define BATCH_BLOCKS 150u     /* more than the host FIFO and the planner take */

static proto_dispatch_t disp;
static uint8_t msg_seq;

static atomic_bool quit;
static atomic_ullong ticks_run;
static unsigned fails;
static unsigned last_action = 99u; /* for the failure message */

static unsigned rnd(unsigned *s)
{
    *s = *s * 1103515245u + 12345u;
    return (*s >> 16) & 0x7FFFu;
}

static void *tick_thread(void *arg)
{
    unsigned s = 4242u;
    uint64_t k = 0;
    (void)arg;
    while (!atomic_load(&quit)) {
        const motion_ref_t *r = drive_test_ref(); /* the tick's own state */
        volatile unsigned spin;
        unsigned i, n = rnd(&s) % 256u;
        for (i = 0; i < AXES; i++) {
            hal_sim_set_counter(i, (uint32_t)(int32_t)r->pos[i], true);
        }
        k++;
        hal_sim_set_time_ns(k * (1000000000u / TICK_HZ));
        {
            const drive_tick_out_t *t = drive_tick(calib_sampling());
            if (t != NULL) {
                calib_tick(t->st, t->vel_ref);
            }
        }
        atomic_store(&ticks_run, k);
        for (spin = 0; spin < n; spin++) {
        }
        if (n % 8u == 0u) {
            sched_yield();
        }
    }
    return NULL;
}

static uint64_t now(void)
{
    return atomic_load(&ticks_run);
}

static void check(int ok, const char *what, unsigned round, const drive_status_t *st)
{
    if (!ok) {
        fails++;
        fprintf(stderr,
                "tsan_drive: round %u (previous action %u): %s (state %d faults 0x%x blocks_done "
                "%u ref %lld %lld %lld)\n",
                round, last_action, what, (int)st->state, st->faults, st->blocks_done,
                (long long)st->ref[0], (long long)st->ref[1], (long long)st->ref[2]);
        atomic_store(&quit, true);
        exit(1);
    }
}

/* The main loop's background work, as a port runs it. */
static void poll(void)
{
    calib_poll();
    drive_poll();
    proto_dispatch_poll(&disp, (uint32_t)(now() * 100u), NULL, NULL);
}

/* Poll until the status says `want` and blocks_done `done` (< 0: any). */
static drive_status_t wait_for(drive_state_t want, long done, unsigned round, const char *what)
{
    drive_status_t st;
    uint64_t t0 = now();
    for (;;) {
        drive_status(&st);
        if (st.state == want && (done < 0 || st.blocks_done == (uint32_t)done)) {
            return st;
        }
        if (now() - t0 > WAIT_TICKS) {
            check(0, what, round, &st);
        }
        poll();
        sched_yield();
    }
}

/* Queue a line from q by a random small move; q becomes its end. */
static void queue_line(pos_nm_t q[AXES], unsigned *s, unsigned round, uint32_t tag)
{
    drive_block_t b;
    drive_status_t st;
    drive_result_t r;
    unsigned i;
    uint64_t t0 = now();
    memset(&b, 0, sizeof b);
    b.kind = DRIVE_BLOCK_LINE;
    b.tag = tag;
    b.feed_nm_s = FEED;
    for (i = 0; i < AXES; i++) {
        q[i] += (pos_nm_t)(rnd(s) % 200001u) - 100000;
        b.target[i] = q[i];
    }
    b.exact_stop = rnd(s) % 2u == 0u;
    while ((r = drive_queue_block(&b)) == DRIVE_E_FULL && now() - t0 < WAIT_TICKS) {
        poll();
    }
    drive_status(&st);
    if (r != DRIVE_OK) {
        fprintf(stderr, "tsan_drive: queue_block: %d\n", (int)r);
    }
    check(r == DRIVE_OK, "queue_block refused", round, &st);
}

static void polls(unsigned n);

/* A job of BATCH_BLOCKS random small lines from q in queue_batch messages
 * (sent again from the block expected while the ring is full); q becomes
 * its end. */
static void batch_job(pos_nm_t q[AXES], unsigned *s, unsigned round)
{
    static pos_nm_t tg[BATCH_BLOCKS][AXES];
    drive_status_t st;
    uint32_t next = 0, base;
    unsigned i, a;
    uint64_t t0 = now();
    int64_t pt0[PROTO_MAX_AXES] = {0, 0, 0, 0};

    drive_status(&st);
    base = st.blocks_done;
    for (i = 0; i < AXES; i++) {
        pt0[i] = q[i];
    }
    for (i = 0; i < BATCH_BLOCKS; i++) {
        for (a = 0; a < AXES; a++) {
            q[a] += (pos_nm_t)(rnd(s) % 20001u) - 10000;
            tg[i][a] = q[a];
        }
    }
    while (next < BATCH_BLOCKS) {
        proto_queue_batch_t m;
        proto_batch_reply_t r;
        proto_batch_block_t b;
        uint8_t in[PROTO_MSG_MAX], out[PROTO_MSG_MAX];
        int64_t pt[PROTO_MAX_AXES];
        uint64_t feed = 0;
        size_t n;

        memset(&b, 0, sizeof b);
        memset(&m, 0, sizeof m);
        for (a = 0; a < PROTO_MAX_AXES; a++) {
            pt[a] = next == 0u ? pt0[a] : (a < AXES ? tg[next - 1u][a] : 0);
        }
        m.first_seq = round * 1000u + next; /* each job at a new block number */
        m.flags = next == 0u ? (uint8_t)(1u << PROTO_BATCH_FLAG_START) : 0u;
        b.kind = PROTO_BATCH_KIND_LINE;
        b.feed = FEED;
        for (i = next; i < BATCH_BLOCKS && m.count < 40u; i++) {
            for (a = 0; a < AXES; a++) {
                b.target[a] = tg[i][a];
            }
            n = proto_batch_put(m.data + m.data_len, sizeof m.data - m.data_len, &b, pt, &feed,
                                i == next);
            if (n == 0u) {
                break; /* the batch is full */
            }
            m.data_len = (uint16_t)(m.data_len + n);
            m.count++;
        }
        in[0] = PROTO_MSG_QUEUE_BATCH;
        in[1] = ++msg_seq;
        n = proto_queue_batch_encode(&m, in + 2, sizeof in - 2);
        n = proto_dispatch_handle(&disp, in, n + 2u, (uint32_t)(now() * 100u), out, sizeof out);
        drive_status(&st);
        check(n > 2u && out[0] == PROTO_MSG_BATCH_REPLY &&
                  proto_batch_reply_decode(out + 2, n - 2u, &r),
              "queue_batch not answered", round, &st);
        check(r.status == PROTO_ERROR_CODE_NONE || r.status == PROTO_ERROR_CODE_QUEUE_FULL,
              "queue_batch refused", round, &st);
        next = r.next_seq - round * 1000u;
        if (r.status != PROTO_ERROR_CODE_NONE) {
            polls(64u);
        }
        check(now() - t0 < WAIT_TICKS, "batch job stalled", round, &st);
    }
    st = wait_for(DRIVE_IDLE, (long)(base + BATCH_BLOCKS), round, "batch job did not finish");
    for (a = 0; a < AXES; a++) {
        check(st.ref[a] == q[a], "batch job ended off its end point", round, &st);
    }
    check(st.tag == round * 1000u + BATCH_BLOCKS - 1u,
          "batch job's last block is not the last done", round, &st);
}

static void polls(unsigned n)
{
    while (n-- > 0u) {
        poll();
        if (n % 16u == 0u) {
            sched_yield();
        }
    }
}

static void round_run(unsigned round, unsigned *s)
{
    drive_status_t st;
    pos_nm_t q[AXES];
    drive_result_t r;
    uint32_t base;
    unsigned i, k = 1u + rnd(s) % 3u, action = rnd(s) % 4u;
    uint64_t t0 = now();

    drive_status(&st);
    for (i = 0; i < AXES; i++) {
        q[i] = st.pos[i]; /* enable holds the measured position */
    }
    while ((r = drive_enable(true)) == DRIVE_E_BUSY && now() - t0 < WAIT_TICKS) {
        poll(); /* a disable the tick has not applied yet */
    }
    drive_status(&st);
    check(r == DRIVE_OK, "enable refused", round, &st);
    if (round % 3u == 0u) {
        batch_job(q, s, round);
        drive_status(&st);
    }
    base = st.blocks_done;
    for (i = 0; i < k; i++) {
        queue_line(q, s, round, round * 4u + i);
        if (rnd(s) % 2u == 0u) {
            polls(rnd(s) % 64u);
        }
    }
    polls(rnd(s) % 2000u);
    switch (action) {
    case 0: /* finish */
        st = wait_for(DRIVE_IDLE, (long)(base + k), round, "job did not finish");
        for (i = 0; i < AXES; i++) {
            check(st.ref[i] == q[i], "job ended off its end point", round, &st);
        }
        break;
    case 1: /* stop, then a new block from the stop point */
        drive_stop();
        st = wait_for(DRIVE_IDLE, -1, round, "stop did not reach IDLE");
        check(st.blocks_done >= base && st.blocks_done <= base + k, "blocks_done after stop", round,
              &st);
        base = st.blocks_done;
        for (i = 0; i < AXES; i++) {
            q[i] = st.ref[i];
        }
        queue_line(q, s, round, 0xF000u + round);
        st = wait_for(DRIVE_IDLE, (long)base + 1, round, "job after stop did not finish");
        for (i = 0; i < AXES; i++) {
            check(st.ref[i] == q[i], "job after stop ended off its end point", round, &st);
        }
        break;
    case 2: /* disable */
        drive_enable(false);
        (void)wait_for(DRIVE_DISABLED, -1, round, "disable");
        break;
    default: /* e-stop, fault reset */
        drive_estop();
        st = wait_for(DRIVE_FAULT, -1, round, "estop");
        check(st.faults == DRIVE_FAULT_ESTOP, "faults after estop", round, &st);
        check(drive_fault_reset() == DRIVE_OK, "fault_reset refused", round, &st);
        (void)wait_for(DRIVE_DISABLED, -1, round, "fault_reset");
        break;
    }
    drive_status(&st);
    check(st.faults == 0u, "fault latched", round, &st);
    last_action = action;
}

int main(void)
{
    drive_config_t cfg;
    pthread_t th;
    unsigned i, s = 2026u;

    hal_sim_reset();
    (void)flash_sim_configure(FLASH_SIM_DEFAULT_BASE, FLASH_SIM_DEFAULT_SIZE,
                              FLASH_SIM_DEFAULT_PAGE, FLASH_SIM_DEFAULT_WRITE);
    drive_config_default(&cfg, TICK_HZ, AXES);
    for (i = 0; i < AXES; i++) {
        cfg.enc_counter[i] = true;
        hal_sim_set_counter(i, 0u, true);
    }
    cfg.start_delay_ms = 2u;
    if (drive_init(&cfg) != DRIVE_OK) {
        fprintf(stderr, "tsan_drive: drive_init refused\n");
        return 1;
    }
    calib_init();
    {
        proto_identity_t id = {0x000100u, 0u, 0u, TICK_HZ, 1u, 0u, 1u, (uint8_t)AXES};

        if (!proto_dispatch_init(&disp, &id, 0u)) {
            return 1;
        }
        disp.comm_timeout_ms = 0; /* the rounds send no keep-alive */
    }
    if (pthread_create(&th, NULL, tick_thread, NULL) != 0) {
        return 1;
    }
    for (i = 0; i < ROUNDS; i++) {
        round_run(i, &s);
    }
    atomic_store(&quit, true);
    pthread_join(th, NULL);
    printf("tsan_drive: %u rounds, %llu ticks, %u failures\n", ROUNDS,
           (unsigned long long)atomic_load(&ticks_run), fails);
    return fails == 0u ? 0 : 1;
}
