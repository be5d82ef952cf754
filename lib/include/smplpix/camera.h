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

/* Framing a subject as a scanner photo does (docs/synth.md, "Framing"; lib/render/frame.c): a
 * camera at `dist` from the centre of the points' 3-D bounding box, looking at it from azimuth az
 * (radians; 0 = the camera on +Z of the centre) and elevation el (radians, |el| < pi/2; positive
 * = above), Y up, whose focal length (square pixels) and principal point make the points'
 * projected bounding box fill `fill` (0 < fill <= 1) of the image height, or of its width when
 * the box is wider than the image allows, centred in the image: a margin of (1 - fill) / 2 of
 * the image on either side of the limiting dimension, so hands and feet stay in. dist <= 0: the
 * default, SPX_FRAME_DISTANCE times the box's largest side (about 3.5 m for a standing adult).
 * SPX_FRAME_FILL is the fill `smplpix demo` and `dataset --orbit` use; `synth` draws
 * it per view from [SPX_FRAME_FILL_MIN, SPX_FRAME_FILL_MAX]. A portrait image (e.g. 192x256)
 * suits a standing person: the box then fills the height. Errors: no points, a point not
 * finite, points without extent, a point at or behind the camera (dist too small). */
#define SPX_FRAME_FILL 0.9
#define SPX_FRAME_FILL_MIN 0.84
#define SPX_FRAME_FILL_MAX 0.94
#define SPX_FRAME_DISTANCE 2.0
spx_status spx_camera_frame(spx_ctx *ctx, int64_t n, const float *pts, int32_t width, int32_t height, double az,
                            double el, double dist, double fill, spx_camera *out);
/* The bounding box [u0, v0, u1, v1] (pixels, continuous: u = u'/d as in the projection) of the
 * n points (xyz floats) seen through cam; a point at or behind the camera is an error. */
spx_status spx_camera_bbox(spx_ctx *ctx, const spx_camera *cam, int64_t n, const float *pts, double box[4]);

#ifdef __cplusplus
}
#endif
#endif
