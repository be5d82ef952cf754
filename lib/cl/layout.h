/* Private: image layout conversions (device + plain-C reference). */
#ifndef SPX_CL_LAYOUT_H
#define SPX_CL_LAYOUT_H
#include "cl/cl_internal.h"
spx_status spx_cl_hwc_to_nchw(spx_ctx *ctx, cl_mem src, cl_mem dst, int n, int c, int h, int w);
spx_status spx_cl_nchw_to_hwc(spx_ctx *ctx, cl_mem src, cl_mem dst, int n, int c, int h, int w);
void spx_ref_hwc_to_nchw(const float *src, float *dst, int n, int c, int h, int w);
void spx_ref_nchw_to_hwc(const float *src, float *dst, int n, int c, int h, int w);
#endif
