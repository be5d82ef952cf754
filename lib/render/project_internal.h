/* Private: the projection on device buffers (kernels/project.cl). The public API is
 * smplpix/render.h: host arrays (spx_project), or a device tensor for the network without a host
 * round trip (spx_project_to_tensor, built on spx_project_device). */
#ifndef SPX_RENDER_PROJECT_INTERNAL_H
#define SPX_RENDER_PROJECT_INTERNAL_H

#include "cl/cl_internal.h"
#include "render/sort.h"
#include "smplpix/render.h"

#define SPX_CAM_FLOATS 21 /* K (3x3 row-major), R (3x3 row-major), t — as in kernels/project.cl */

/* The projection's algorithms; every one gives the reference's bits. */
typedef enum spx_proj_path {
  SPX_PROJ_PATH_AUTO = 0, /* chosen by the tunables SPX_PROJ_ZBUF, SPX_PROJ_ONE_MAX, SPX_PROJ_FAST_MAX */
  SPX_PROJ_PATH_FUSED,    /* one single-work-group launch: sort + unique + scatter (small inputs) */
  SPX_PROJ_PATH_RADIX,    /* radix sort, then unique + scatter */
  SPX_PROJ_PATH_ZBUF,     /* z-buffer per part + merge (CPU-class devices) */
  SPX_PROJ_PATH_ONE,      /* one launch of one work-group: clear, project, resolve (small inputs, CPU) */
  SPX_PROJ_NPATHS
} spx_proj_path;

struct spx_projector {
  spx_sorter sorter;
  spx_cl_buf pos, col, cams, keys, vals, img, win; /* grow-only scratch */
  spx_cl_buf gimg, gcol, gpos, vpix, zb;
  spx_cl_buf zb1, touched, ntouched; /* one-launch path: its z-buffer, the pixels (and their images) its
                                        last call wrote into img (and win), their count */
  spx_cl_buf dummy;
  spx_proj_path last_path; /* path of the last forward (for tests/benchmarks) */
  size_t zb_clear, zb1_clear; /* leading bytes of zb / zb1 known to be empty (all ones); 0 after a failed call */
  /* One-launch path state: img (win) holds the background except at the pixels listed in touched, for
   * images of one_hw pixels, one_npix pixels in all, layout one_layout; 0 when unknown (another
   * path or a copy wrote there, the buffer was reallocated, a call failed). */
  int one_img_ok, one_win_ok, one_layout;
  uint32_t one_hw, one_npix;
  int ncams_on_device;                  /* cameras in `cams` equal to cam_host (0: unknown) */
  float cam_host[16 * SPX_CAM_FLOATS]; /* what was uploaded last, to skip repeated uploads */
};

/* Inputs on the device: pos B*N*3 floats, col B*N*3 floats or NULL (white). */
typedef struct spx_project_dev_args {
  int32_t batch, nverts;
  cl_mem pos, col;
  int32_t ncams;
  const spx_camera *cams;
  spx_layout layout;
} spx_project_dev_args;

/* Forward into device buffers: out B*C*4*H*W floats (layout as asked; the network wants
 * SPX_LAYOUT_NCHW), winners B*C*H*W ints or NULL. Only enqueues work. path: SPX_PROJ_PATH_AUTO, or
 * the one to run (tests compare all); auto takes SPX_PROJ_PATH_ONE only into the projector's own
 * img / win, whose background it keeps between calls (see struct spx_projector). */
spx_status spx_project_device(spx_ctx *ctx, spx_projector *p, const spx_project_dev_args *a, cl_mem out,
                              cl_mem winners, spx_proj_path path);

/* Backward on device buffers: adds into gcol / gpos (B*N*3 floats each, either may be NULL).
 * winners must come from spx_project_device (unique per image). */
spx_status spx_project_backward_device(spx_ctx *ctx, spx_projector *p, const spx_project_dev_args *a, cl_mem winners,
                                       cl_mem grad_img, cl_mem gcol, cl_mem gpos);

/* Checks shared by the device path and the reference: counts, spx_camera_validate on every
 * camera, one size across the batch, K R t finite after rounding to float. */
spx_status spx_project_check(spx_ctx *ctx, const char *fn, int32_t batch, int32_t nverts, int32_t ncams,
                             const spx_camera *cams);

/* The cameras as the kernels and the reference see them (floats, SPX_CAM_FLOATS per camera). */
void spx_project_cam_floats(const spx_camera *cam, float out[SPX_CAM_FLOATS]);

#endif
