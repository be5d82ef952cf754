/* Private: device body forward on cl_mem (for pipelines that keep vertices on the device). */
#ifndef SPX_BODY_LBS_H
#define SPX_BODY_LBS_H
#include "cl/cl_internal.h"
#include "smplpix/body.h"

/* Upload the model's arrays to ctx's device (once; re-uploaded if ctx changes). */
spx_status spx_body_dev_ensure(spx_ctx *ctx, spx_body_model *m);
/* betas B*nbetas (any buffer when nbetas = 0), pose B*K*3, trans B*3, vbase N*3 or NULL (model
 * template); writes verts B*N*3 and joints B*K*3 (both float32). */
spx_status spx_body_forward_cl(spx_ctx *ctx, spx_body_model *m, int32_t batch, int32_t nbetas, cl_mem betas,
                               cl_mem pose, cl_mem trans, cl_mem vbase, cl_mem verts, cl_mem joints);
#endif
