/*
 * sim_abi.h - the layout of the C structures the host tools mirror (ctypes).
 *
 * Specification
 * -------------
 * contour.native (host_tools) declares a Python copy of every C structure
 * it passes through build/host/libcontour.so. Before binding anything it
 * asks the library for the C layout of each one and refuses a library whose
 * layout differs from its copy, so a field added on one side only is an
 * error at load time instead of corrupted memory.
 *
 * sim_abi_sizeof(type): sizeof the C type called `type` (e.g.
 * "sim_status_t"); 0 for a type this file does not know.
 * sim_abi_fields(type): how many fields of it are listed (all of them).
 * sim_abi_offsetof(type, field): offsetof that field; SIZE_MAX for an
 * unknown type or field. Host only, main context.
 */
#ifndef SIM_ABI_H
#define SIM_ABI_H

#include <stddef.h>

size_t sim_abi_sizeof(const char *type);
size_t sim_abi_fields(const char *type);
size_t sim_abi_offsetof(const char *type, const char *field);

#endif /* SIM_ABI_H */
