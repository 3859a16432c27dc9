/*
 * gpiod_fake.c - a link-time fake of the libgpiod v2 calls the Linux port
 * makes (firmware/ports/linux/hal_linux.c), for machines without a GPIO
 * chip. Linked instead of libgpiod; the port is compiled against the real
 * <gpiod.h> (Debian's libgpiod-dev), so the signatures are the library's.
 *
 * Script in  (GPIOD_FAKE_SCRIPT, one command per line, '#' comments):
 *   edge T_US OFFSET LEVEL   the input line OFFSET changes to LEVEL (0/1)
 *                            T_US microseconds after gpiod_chip_open
 *   level OFFSET LEVEL       initial level of an input line (default 0; 1
 *                            for lines requested with a pull-up)
 * Edge events become readable on the request's fd (a timerfd armed for the
 * next due event) at their time, with CLOCK_MONOTONIC time stamps, exactly
 * as the kernel delivers them; an event that does not change the level is
 * still delivered (a glitch the port must handle).
 * Outputs out (GPIOD_FAKE_OUT): every value driven on an output line, one
 * line "T_US OFFSET VALUE", starting with the requested initial values.
 */
#include <errno.h>
#include <gpiod.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/timerfd.h>
#include <time.h>
#include <unistd.h>

#define MAX_LINES  256
#define MAX_EVENTS 65536

struct gpiod_chip {
    int dummy;
};
struct gpiod_request_config {
    char consumer[32];
};
struct gpiod_line_settings {
    enum gpiod_line_direction dir;
    enum gpiod_line_edge edge;
    enum gpiod_line_bias bias;
    enum gpiod_line_value out;
};
struct gpiod_line_config {
    unsigned n;
    unsigned offs[MAX_LINES];
    struct gpiod_line_settings s[MAX_LINES];
};
struct gpiod_line_request {
    unsigned n;
    unsigned offs[MAX_LINES];
    struct gpiod_line_settings s[MAX_LINES];
    int fd; /* timerfd when edges are requested, else -1 */
};
struct gpiod_edge_event {
    enum gpiod_edge_event_type type;
    uint64_t ts;
    unsigned offset;
};
struct gpiod_edge_event_buffer {
    size_t cap, n;
    struct gpiod_edge_event *ev;
};

typedef struct {
    uint64_t t_ns; /* after open */
    unsigned off;
    int level;
} script_ev_t;

static struct {
    bool open;
    uint64_t t0;
    int level[MAX_LINES];
    bool level_set[MAX_LINES];
    script_ev_t ev[MAX_EVENTS];
    size_t nev, next;
    FILE *out;
} fk;

static uint64_t now_ns(void)
{
    struct timespec ts;

    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void load_script(const char *path)
{
    FILE *f = fopen(path, "r");
    char buf[256];

    if (f == NULL) {
        fprintf(stderr, "gpiod_fake: cannot open script %s\n", path);
        exit(90);
    }
    while (fgets(buf, sizeof buf, f) != NULL) {
        unsigned long long t;
        unsigned off;
        int lv;

        if (buf[0] == '#' || buf[0] == '\n') {
            continue;
        }
        if (sscanf(buf, "edge %llu %u %d", &t, &off, &lv) == 3 && off < MAX_LINES &&
            fk.nev < MAX_EVENTS) {
            fk.ev[fk.nev].t_ns = t * 1000u;
            fk.ev[fk.nev].off = off;
            fk.ev[fk.nev].level = lv != 0;
            fk.nev++;
        } else if (sscanf(buf, "level %u %d", &off, &lv) == 2 && off < MAX_LINES) {
            fk.level[off] = lv != 0;
            fk.level_set[off] = true;
        } else {
            fprintf(stderr, "gpiod_fake: bad script line: %s", buf);
            exit(90);
        }
    }
    fclose(f);
}

static void record(unsigned off, int value)
{
    if (fk.out != NULL) {
        fprintf(fk.out, "%llu %u %d\n", (unsigned long long)((now_ns() - fk.t0) / 1000u), off,
                value);
        fflush(fk.out);
    }
}

struct gpiod_chip *gpiod_chip_open(const char *path)
{
    static struct gpiod_chip chip;
    const char *s = getenv("GPIOD_FAKE_SCRIPT"), *o = getenv("GPIOD_FAKE_OUT");

    (void)path;
    if (fk.open) {
        errno = EBUSY;
        return NULL;
    }
    memset(&fk, 0, sizeof fk);
    if (s != NULL && *s != '\0') {
        load_script(s);
    }
    if (o != NULL && *o != '\0') {
        fk.out = fopen(o, "w");
    }
    fk.t0 = now_ns();
    fk.open = true;
    return &chip;
}

void gpiod_chip_close(struct gpiod_chip *chip)
{
    (void)chip;
    if (fk.out != NULL) {
        fclose(fk.out);
    }
    fk.open = false;
}

struct gpiod_request_config *gpiod_request_config_new(void)
{
    return calloc(1, sizeof(struct gpiod_request_config));
}

void gpiod_request_config_free(struct gpiod_request_config *config)
{
    free(config);
}

void gpiod_request_config_set_consumer(struct gpiod_request_config *config, const char *consumer)
{
    snprintf(config->consumer, sizeof config->consumer, "%s", consumer);
}

struct gpiod_line_settings *gpiod_line_settings_new(void)
{
    struct gpiod_line_settings *s = calloc(1, sizeof *s);

    if (s != NULL) {
        s->dir = GPIOD_LINE_DIRECTION_AS_IS;
        s->edge = GPIOD_LINE_EDGE_NONE;
        s->bias = GPIOD_LINE_BIAS_AS_IS;
        s->out = GPIOD_LINE_VALUE_INACTIVE;
    }
    return s;
}

void gpiod_line_settings_free(struct gpiod_line_settings *settings)
{
    free(settings);
}

int gpiod_line_settings_set_direction(struct gpiod_line_settings *s, enum gpiod_line_direction d)
{
    s->dir = d;
    return 0;
}

int gpiod_line_settings_set_edge_detection(struct gpiod_line_settings *s, enum gpiod_line_edge e)
{
    s->edge = e;
    return 0;
}

int gpiod_line_settings_set_bias(struct gpiod_line_settings *s, enum gpiod_line_bias b)
{
    s->bias = b;
    return 0;
}

int gpiod_line_settings_set_output_value(struct gpiod_line_settings *s, enum gpiod_line_value v)
{
    s->out = v;
    return 0;
}

struct gpiod_line_config *gpiod_line_config_new(void)
{
    return calloc(1, sizeof(struct gpiod_line_config));
}

void gpiod_line_config_free(struct gpiod_line_config *config)
{
    free(config);
}

int gpiod_line_config_add_line_settings(struct gpiod_line_config *config,
                                        const unsigned int *offsets, size_t num_offsets,
                                        struct gpiod_line_settings *settings)
{
    size_t i;

    if (config->n + num_offsets > MAX_LINES) {
        errno = E2BIG;
        return -1;
    }
    for (i = 0; i < num_offsets; i++) {
        if (offsets[i] >= MAX_LINES) {
            errno = EINVAL;
            return -1;
        }
        config->offs[config->n] = offsets[i];
        config->s[config->n] = *settings;
        config->n++;
    }
    return 0;
}

static void arm(struct gpiod_line_request *r)
{
    struct itimerspec its;
    uint64_t t;

    memset(&its, 0, sizeof its);
    if (fk.next < fk.nev) {
        t = fk.t0 + fk.ev[fk.next].t_ns;
        its.it_value.tv_sec = (time_t)(t / 1000000000u);
        its.it_value.tv_nsec = (long)(t % 1000000000u);
        if (its.it_value.tv_sec == 0 && its.it_value.tv_nsec == 0) {
            its.it_value.tv_nsec = 1;
        }
    }
    timerfd_settime(r->fd, TFD_TIMER_ABSTIME, &its, NULL);
}

struct gpiod_line_request *gpiod_chip_request_lines(struct gpiod_chip *chip,
                                                    struct gpiod_request_config *req_cfg,
                                                    struct gpiod_line_config *line_cfg)
{
    struct gpiod_line_request *r;
    unsigned i;
    bool edges = false;

    (void)chip;
    (void)req_cfg;
    if (line_cfg == NULL || line_cfg->n == 0u) {
        errno = EINVAL;
        return NULL;
    }
    r = calloc(1, sizeof *r);
    if (r == NULL) {
        return NULL;
    }
    r->n = line_cfg->n;
    r->fd = -1;
    for (i = 0; i < r->n; i++) {
        unsigned o = line_cfg->offs[i];

        r->offs[i] = o;
        r->s[i] = line_cfg->s[i];
        if (r->s[i].dir == GPIOD_LINE_DIRECTION_OUTPUT) {
            fk.level[o] = r->s[i].out == GPIOD_LINE_VALUE_ACTIVE;
            record(o, fk.level[o]);
        } else if (!fk.level_set[o] && r->s[i].bias == GPIOD_LINE_BIAS_PULL_UP) {
            fk.level[o] = 1;
        }
        if (r->s[i].edge != GPIOD_LINE_EDGE_NONE) {
            edges = true;
        }
    }
    if (edges) {
        r->fd = timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK);
        arm(r);
    }
    return r;
}

void gpiod_line_request_release(struct gpiod_line_request *request)
{
    if (request->fd >= 0) {
        close(request->fd);
    }
    free(request);
}

static int find(const struct gpiod_line_request *r, unsigned offset)
{
    unsigned i;

    for (i = 0; i < r->n; i++) {
        if (r->offs[i] == offset) {
            return (int)i;
        }
    }
    return -1;
}

enum gpiod_line_value gpiod_line_request_get_value(struct gpiod_line_request *request,
                                                   unsigned int offset)
{
    if (find(request, offset) < 0) {
        errno = EINVAL;
        return GPIOD_LINE_VALUE_ERROR;
    }
    return fk.level[offset] ? GPIOD_LINE_VALUE_ACTIVE : GPIOD_LINE_VALUE_INACTIVE;
}

int gpiod_line_request_set_value(struct gpiod_line_request *request, unsigned int offset,
                                 enum gpiod_line_value value)
{
    int i = find(request, offset);

    if (i < 0 || request->s[i].dir != GPIOD_LINE_DIRECTION_OUTPUT) {
        errno = EINVAL;
        return -1;
    }
    fk.level[offset] = value == GPIOD_LINE_VALUE_ACTIVE;
    record(offset, fk.level[offset]);
    return 0;
}

int gpiod_line_request_get_fd(struct gpiod_line_request *request)
{
    return request->fd;
}

struct gpiod_edge_event_buffer *gpiod_edge_event_buffer_new(size_t capacity)
{
    struct gpiod_edge_event_buffer *b = calloc(1, sizeof *b);

    if (b == NULL || capacity == 0u) {
        free(b);
        return NULL;
    }
    b->ev = calloc(capacity, sizeof *b->ev);
    if (b->ev == NULL) {
        free(b);
        return NULL;
    }
    b->cap = capacity;
    return b;
}

void gpiod_edge_event_buffer_free(struct gpiod_edge_event_buffer *buffer)
{
    if (buffer != NULL) {
        free(buffer->ev);
        free(buffer);
    }
}

struct gpiod_edge_event *gpiod_edge_event_buffer_get_event(struct gpiod_edge_event_buffer *buffer,
                                                           unsigned long index)
{
    return index < buffer->n ? &buffer->ev[index] : NULL;
}

int gpiod_line_request_read_edge_events(struct gpiod_line_request *request,
                                        struct gpiod_edge_event_buffer *buffer, size_t max_events)
{
    uint64_t exp, now = now_ns();
    size_t n = 0;

    if (request->fd < 0) {
        errno = EINVAL;
        return -1;
    }
    if (read(request->fd, &exp, sizeof exp) < 0 && errno != EAGAIN) {
        return -1;
    }
    buffer->n = 0;
    while (n < max_events && n < buffer->cap && fk.next < fk.nev &&
           fk.t0 + fk.ev[fk.next].t_ns <= now) {
        const script_ev_t *e = &fk.ev[fk.next++];
        int i = find(request, e->off);

        if (i < 0 || request->s[i].edge == GPIOD_LINE_EDGE_NONE) {
            fk.level[e->off] = e->level; /* a line of another request */
            continue;
        }
        fk.level[e->off] = e->level;
        buffer->ev[n].type =
            e->level ? GPIOD_EDGE_EVENT_RISING_EDGE : GPIOD_EDGE_EVENT_FALLING_EDGE;
        buffer->ev[n].ts = fk.t0 + e->t_ns;
        buffer->ev[n].offset = e->off;
        n++;
    }
    buffer->n = n;
    arm(request);
    return (int)n;
}

enum gpiod_edge_event_type gpiod_edge_event_get_event_type(struct gpiod_edge_event *event)
{
    return event->type;
}

uint64_t gpiod_edge_event_get_timestamp_ns(struct gpiod_edge_event *event)
{
    return event->ts;
}

unsigned int gpiod_edge_event_get_line_offset(struct gpiod_edge_event *event)
{
    return event->offset;
}
