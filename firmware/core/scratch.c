/* Main-context scratch area: scratch.h. */
#include "scratch.h"

#include "comp.h"
#include "comp_store.h"
#include "servo.h"

/* the users: the area is as large as the largest */
typedef union {
    comp_table_t table;
    servo_t servo;
    uint8_t blob[COMP_STORE_BLOB_MAX];
    uint64_t align;
} scratch_users_t;

static union {
    scratch_users_t users;
    uint8_t b[sizeof(scratch_users_t)];
} area;                        /* main */
static scratch_owner_t holder; /* main */
static uint32_t collisions;    /* main */

void *scratch_claim(scratch_owner_t owner, size_t bytes)
{
    if (holder != SCRATCH_FREE || owner == SCRATCH_FREE || bytes > sizeof area) {
        collisions++;
        return NULL;
    }
    holder = owner;
    return area.b;
}

void scratch_release(scratch_owner_t owner)
{
    if (holder != owner) {
        collisions++;
        return;
    }
    holder = SCRATCH_FREE;
}

scratch_owner_t scratch_owner(void)
{
    return holder;
}

uint32_t scratch_collisions(void)
{
    return collisions;
}

size_t scratch_bytes(void)
{
    return sizeof area;
}
