/* Pinhole cameras (DESIGN.md): (u', v', d) = K (R x + t), u = u'/d, v = v'/d; the vertex lands
 * in column floor(u), row floor(v). */
#ifndef SMPLPIX_CAMERA_H
#define SMPLPIX_CAMERA_H

#include "smplpix/core.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SPX_CAMERA_MAX_SIZE 16384

typedef struct spx_camera {
  int32_t width, height;
  double K[3][3]; /* upper-triangular: K[1][0] == K[2][0] == K[2][1] == 0 and K[2][2] == 1;
                     K[0][0] > 0, K[1][1] > 0 (focal lengths in pixels) */
  double R[3][3]; /* orthonormal within 1e-4 (rows and columns), det > 0 */
  double t[3];
} spx_camera;

/* Load a camera JSON file: one object or an array of objects. *cams is malloc'd (free()).
 * Errors name the file, the array index and the key (e.g. "cam.json: [2].R: not orthonormal"). */
spx_status spx_camera_load(spx_ctx *ctx, const char *path, spx_camera **cams, int *count);
spx_status spx_camera_parse(spx_ctx *ctx, const char *name, const char *text, size_t len, spx_camera **cams,
                            int *count);
/* Validate one camera (K upper-triangular as above with positive focal lengths, R orthonormal
 * within 1e-4 with det > 0, 0 < width,height <= 16384, all finite). Non-finite values give
 * SPX_E_NUMERIC, impossible cameras SPX_E_CAMERA; in files, wrong types and missing keys give
 * SPX_E_FORMAT ("cam.json: [1].t: expected an array of 3 numbers"). */
spx_status spx_camera_validate(spx_ctx *ctx, const char *name, const spx_camera *cam);
/* Save one camera (count == 1 writes an object) or an array, atomically. */
spx_status spx_camera_save(spx_ctx *ctx, const char *path, const spx_camera *cams, int count);

/* A camera at `eye` looking at `target` with `up` roughly up (OpenCV axes: x right, y down,
 * z forward), focal length in pixels, principal point at the image centre. */
spx_status spx_camera_look_at(spx_ctx *ctx, int32_t width, int32_t height, double focal_px, const double eye[3],
                              const double target[3], const double up[3], spx_camera *out);

#ifdef __cplusplus
}
#endif
#endif
