/* The bottom of lib/cl, calling nothing else of it (the order of lib/cl: lib/cl/cl_internal.h):
 * OpenCL error names, the status (and the context's message) of a cl_int, and the open-device
 * check of every entry point. */
#include "cl/cl_internal.h"

const char *spx_cl_error_name(cl_int e) {
  switch (e) {
#define C(x) case x: return #x;
    C(CL_SUCCESS) C(CL_DEVICE_NOT_FOUND) C(CL_DEVICE_NOT_AVAILABLE) C(CL_COMPILER_NOT_AVAILABLE)
    C(CL_MEM_OBJECT_ALLOCATION_FAILURE) C(CL_OUT_OF_RESOURCES) C(CL_OUT_OF_HOST_MEMORY)
    C(CL_PROFILING_INFO_NOT_AVAILABLE) C(CL_MEM_COPY_OVERLAP) C(CL_IMAGE_FORMAT_MISMATCH)
    C(CL_IMAGE_FORMAT_NOT_SUPPORTED) C(CL_BUILD_PROGRAM_FAILURE) C(CL_MAP_FAILURE)
    C(CL_MISALIGNED_SUB_BUFFER_OFFSET) C(CL_COMPILE_PROGRAM_FAILURE) C(CL_LINKER_NOT_AVAILABLE)
    C(CL_LINK_PROGRAM_FAILURE) C(CL_INVALID_VALUE) C(CL_INVALID_DEVICE_TYPE) C(CL_INVALID_PLATFORM)
    C(CL_INVALID_DEVICE) C(CL_INVALID_CONTEXT) C(CL_INVALID_QUEUE_PROPERTIES) C(CL_INVALID_COMMAND_QUEUE)
    C(CL_INVALID_HOST_PTR) C(CL_INVALID_MEM_OBJECT) C(CL_INVALID_BINARY) C(CL_INVALID_BUILD_OPTIONS)
    C(CL_INVALID_PROGRAM) C(CL_INVALID_PROGRAM_EXECUTABLE) C(CL_INVALID_KERNEL_NAME)
    C(CL_INVALID_KERNEL_DEFINITION) C(CL_INVALID_KERNEL) C(CL_INVALID_ARG_INDEX) C(CL_INVALID_ARG_VALUE)
    C(CL_INVALID_ARG_SIZE) C(CL_INVALID_KERNEL_ARGS) C(CL_INVALID_WORK_DIMENSION)
    C(CL_INVALID_WORK_GROUP_SIZE) C(CL_INVALID_WORK_ITEM_SIZE) C(CL_INVALID_GLOBAL_OFFSET)
    C(CL_INVALID_EVENT_WAIT_LIST) C(CL_INVALID_EVENT) C(CL_INVALID_OPERATION) C(CL_INVALID_BUFFER_SIZE)
    C(CL_INVALID_GLOBAL_WORK_SIZE)
#undef C
  default: return "CL_UNKNOWN_ERROR";
  }
}

/* CL_OUT_OF_RESOURCES is not out of memory: drivers return it for a launch the device cannot
 * hold (registers or local memory of the work-group) and after a kernel faults, so it is a
 * device error (SPX_E_CL) here, except after a buffer transfer (check_mem below), where drivers
 * that allocate on first use report a failed allocation with it. */
spx_status spx_cl_check(spx_ctx *ctx, cl_int err, const char *what) {
  if (err == CL_SUCCESS) return SPX_OK;
  spx_status st = (err == CL_MEM_OBJECT_ALLOCATION_FAILURE || err == CL_INVALID_BUFFER_SIZE) ? SPX_E_DEVMEM : SPX_E_CL;
  if (err == CL_OUT_OF_RESOURCES)
    return spx_fail(ctx, st, "%s: %s (%d): the device lacked a resource for it (registers or local memory of the "
                    "work-group, or a kernel faulted)", what, spx_cl_error_name(err), (int)err);
  return spx_fail(ctx, st, "%s: %s (%d)", what, spx_cl_error_name(err), (int)err);
}

spx_status spx_cl_require(spx_ctx *ctx, const char *what) {
  if (!ctx) return SPX_E_ARG;
  if (!ctx->dev)
    return spx_fail(ctx, SPX_E_STATE, "%s: no OpenCL device is open (call spx_device_open first)", what);
  return SPX_OK;
}
