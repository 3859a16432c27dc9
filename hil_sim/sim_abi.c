/* sim_abi.c - C layout of the structures the host mirrors (see sim_abi.h). */
#include "sim_abi.h"

#include <stdint.h>
#include <string.h>

#include "comp2d.h"
#include "drive.h"
#include "estimator.h"
#include "gcode_scan.h"
#include "planner.h"
#include "proto_msgs.h"
#include "sim.h"

typedef struct {
    const char *type;
    const char *field; /* NULL: the row gives sizeof(type) */
    size_t value;
} sim_abi_entry_t;

#define SIM_ABI_SIZE(type)         #type, NULL, sizeof(type)
#define SIM_ABI_FIELD(type, field) #type, #field, offsetof(type, field)

/* Every structure contour.native mirrors (its MIRRORS), every field. */
static const sim_abi_entry_t sim_abi_table[] = {
    {SIM_ABI_SIZE(sim_status_t)},
    {SIM_ABI_SIZE(drive_block_t)},
    {SIM_ABI_SIZE(plan_profile_t)},
    {SIM_ABI_SIZE(plan_move_t)},
    {SIM_ABI_SIZE(plan_est_t)},
    {SIM_ABI_SIZE(proto_msg_info_t)},
    {SIM_ABI_SIZE(gcode_scan_t)},
    {SIM_ABI_SIZE(comp2d_map_t)},
    {SIM_ABI_FIELD(comp2d_map_t, version)},
    {SIM_ABI_FIELD(comp2d_map_t, nx)},
    {SIM_ABI_FIELD(comp2d_map_t, ny)},
    {SIM_ABI_FIELD(comp2d_map_t, shift)},
    {SIM_ABI_FIELD(comp2d_map_t, x0)},
    {SIM_ABI_FIELD(comp2d_map_t, y0)},
    {SIM_ABI_FIELD(comp2d_map_t, dx)},
    {SIM_ABI_FIELD(comp2d_map_t, dy)},
    {SIM_ABI_FIELD(comp2d_map_t, inv_dx)},
    {SIM_ABI_FIELD(comp2d_map_t, inv_dy)},
    {SIM_ABI_FIELD(comp2d_map_t, g)},
    {SIM_ABI_FIELD(sim_status_t, state)},
    {SIM_ABI_FIELD(sim_status_t, faults)},
    {SIM_ABI_FIELD(sim_status_t, queue_free)},
    {SIM_ABI_FIELD(sim_status_t, blocks_done)},
    {SIM_ABI_FIELD(sim_status_t, tag)},
    {SIM_ABI_FIELD(sim_status_t, tick)},
    {SIM_ABI_FIELD(sim_status_t, queued_time_ns)},
    {SIM_ABI_FIELD(drive_block_t, kind)},
    {SIM_ABI_FIELD(drive_block_t, tag)},
    {SIM_ABI_FIELD(drive_block_t, target)},
    {SIM_ABI_FIELD(drive_block_t, feed_nm_s)},
    {SIM_ABI_FIELD(drive_block_t, exact_stop)},
    {SIM_ABI_FIELD(drive_block_t, plane)},
    {SIM_ABI_FIELD(drive_block_t, centre_u)},
    {SIM_ABI_FIELD(drive_block_t, centre_v)},
    {SIM_ABI_FIELD(drive_block_t, sense)},
    {SIM_ABI_FIELD(drive_block_t, dwell_ms)},
    {SIM_ABI_FIELD(plan_profile_t, v_max)},
    {SIM_ABI_FIELD(plan_profile_t, a_max)},
    {SIM_ABI_FIELD(plan_profile_t, j_max)},
    {SIM_ABI_FIELD(plan_profile_t, corner_dv)},
    {SIM_ABI_FIELD(plan_profile_t, corner_acc)},
    {SIM_ABI_FIELD(plan_profile_t, junction_dev_nm)},
    {SIM_ABI_FIELD(plan_profile_t, min_block_ns)},
    {SIM_ABI_FIELD(plan_profile_t, mbt_window)},
    {SIM_ABI_FIELD(plan_profile_t, corner)},
    {SIM_ABI_FIELD(plan_profile_t, shape)},
    {SIM_ABI_FIELD(plan_move_t, target)},
    {SIM_ABI_FIELD(plan_move_t, feed)},
    {SIM_ABI_FIELD(plan_move_t, dwell_ns)},
    {SIM_ABI_FIELD(plan_move_t, tag)},
    {SIM_ABI_FIELD(plan_move_t, flags)},
    {SIM_ABI_FIELD(plan_est_t, len_nm)},
    {SIM_ABI_FIELD(plan_est_t, v_entry)},
    {SIM_ABI_FIELD(plan_est_t, v_peak)},
    {SIM_ABI_FIELD(plan_est_t, v_exit)},
    {SIM_ABI_FIELD(plan_est_t, v_max)},
    {SIM_ABI_FIELD(plan_est_t, t_acc_ns)},
    {SIM_ABI_FIELD(plan_est_t, t_cruise_ns)},
    {SIM_ABI_FIELD(plan_est_t, t_dec_ns)},
    {SIM_ABI_FIELD(plan_est_t, t_total_ns)},
    {SIM_ABI_FIELD(plan_est_t, t_mbt_ns)},
    {SIM_ABI_FIELD(plan_est_t, tag)},
    {SIM_ABI_FIELD(plan_est_t, flags)},
    {SIM_ABI_FIELD(proto_msg_info_t, id)},
    {SIM_ABI_FIELD(proto_msg_info_t, dir)},
    {SIM_ABI_FIELD(proto_msg_info_t, reply)},
    {SIM_ABI_FIELD(proto_msg_info_t, can_func)},
    {SIM_ABI_FIELD(proto_msg_info_t, min_len)},
    {SIM_ABI_FIELD(proto_msg_info_t, max_len)},
    {SIM_ABI_FIELD(proto_msg_info_t, name)},
    {SIM_ABI_FIELD(gcode_scan_t, pos)},
    {SIM_ABI_FIELD(gcode_scan_t, origin)},
    {SIM_ABI_FIELD(gcode_scan_t, scale)},
    {SIM_ABI_FIELD(gcode_scan_t, feed)},
    {SIM_ABI_FIELD(gcode_scan_t, tol)},
    {SIM_ABI_FIELD(gcode_scan_t, row_base)},
    {SIM_ABI_FIELD(gcode_scan_t, motion)},
    {SIM_ABI_FIELD(gcode_scan_t, absolute)},
    {SIM_ABI_FIELD(gcode_scan_t, arc_abs)},
    {SIM_ABI_FIELD(gcode_scan_t, plane)},
    {SIM_ABI_FIELD(gcode_scan_t, stop)},
    {SIM_ABI_FIELD(gcode_scan_t, line)},
    {SIM_ABI_FIELD(gcode_scan_t, rows)},
    {SIM_ABI_FIELD(gcode_scan_t, cap)},
    {SIM_ABI_FIELD(gcode_scan_t, arcs)},
    {SIM_ABI_FIELD(gcode_scan_t, gseen)},
    {SIM_ABI_FIELD(gcode_scan_t, kind)},
    {SIM_ABI_FIELD(gcode_scan_t, end)},
    {SIM_ABI_FIELD(gcode_scan_t, feeds)},
    {SIM_ABI_FIELD(gcode_scan_t, stops)},
    {SIM_ABI_FIELD(gcode_scan_t, lines)},
    {SIM_ABI_FIELD(gcode_scan_t, arc_row)},
    {SIM_ABI_FIELD(gcode_scan_t, arc_centre)},
};

#define SIM_ABI_ROWS (sizeof(sim_abi_table) / sizeof(sim_abi_table[0]))

size_t sim_abi_sizeof(const char *type)
{
    size_t i;

    for (i = 0; type != NULL && i < SIM_ABI_ROWS; i++) {
        if (sim_abi_table[i].field == NULL && strcmp(sim_abi_table[i].type, type) == 0) {
            return sim_abi_table[i].value;
        }
    }
    return 0;
}

size_t sim_abi_fields(const char *type)
{
    size_t i;
    size_t n = 0;

    for (i = 0; type != NULL && i < SIM_ABI_ROWS; i++) {
        if (sim_abi_table[i].field != NULL && strcmp(sim_abi_table[i].type, type) == 0) {
            n++;
        }
    }
    return n;
}

size_t sim_abi_offsetof(const char *type, const char *field)
{
    size_t i;

    for (i = 0; type != NULL && field != NULL && i < SIM_ABI_ROWS; i++) {
        if (sim_abi_table[i].field != NULL && strcmp(sim_abi_table[i].type, type) == 0 &&
            strcmp(sim_abi_table[i].field, field) == 0) {
            return sim_abi_table[i].value;
        }
    }
    return SIZE_MAX;
}
