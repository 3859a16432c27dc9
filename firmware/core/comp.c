/*
 * comp.c - compensation hook. Until the calibration issue defines the table,
 * no comp_table_t can exist, so every call is the identity (NULL table).
 */
#include "comp.h"

pos_nm_t comp_correct(const comp_table_t *table, pos_nm_t pos_nm, comp_dir_t dir)
{
    (void)table;
    (void)dir;
    return pos_nm;
}
