/* Bodies and depth frames for bench_register_views (benchmark code, not library code).
 *
 * Bodies outside the shipped body model's shape space, so that a registration cannot be right
 * by reproducing the body exactly (rs_body_outside, k = 0..RS_NOUTSIDE-1):
 *   0 woman          data/body/human_woman.obj (SMPL topology, another body model) as it is
 *   1 woman-large    the same, 12% wider and 18% deeper about her centre, with four smooth
 *                    bulges of 1.5-3 cm along the normals (belly, hips, back: a heavier build)
 *   2 clothed-a      a `smplpix synth` subject (loose shirt and trousers with folds, hair volume,
 *                    shoes: the surface is not the body), posed at random
 *   3 clothed-b      another one, another pose
 *   4 betas-x2       the shipped body with shape coefficients 1-9 at +-4 (twice the range that
 *                    synth_body draws, far in the prior's tail; coefficient 0, its overall size,
 *                    at +0.5: 1.81 m tall), posed at random
 *   5 displaced      the shipped body (random shape and pose) with six smooth 2-4 cm bulges
 *                    along the normals and its width x 1.1: no shape coefficients reproduce it
 * The true surface of each is what the scans sample and what the score measures against.
 *
 * Depth frames (rs_depth_frame): tests/fit_view.h's view_room_depth, the body's depth image through
 * a camera (the rasterizer's depth channel), optionally standing in a room (a floor under the feet,
 * four walls 3.2 m from the body's centre), with flying pixels at the body's silhouette (half of
 * the pixels on either side of a depth jump over 5 cm take a random mix of the two depths), 1 mm
 * Gaussian noise and whole millimetres (what a 16-bit PNG holds). */
#ifndef SPX_BENCH_REGISTER_SCENES_H
#define SPX_BENCH_REGISTER_SCENES_H

#include <stdint.h>

#include "smplpix/smplpix.h"

#define RS_NOUTSIDE 6

typedef struct rs_body {
  char name[32];
  int32_t nv, nf;
  double *V;   /* nv*3, metres, y up, facing +z */
  int32_t *F;  /* nf*3 */
} rs_body;

/* Body k of the list above; woman: human_woman.obj; parts: the synth part map. Returns 0, or -1
 * with the reason on ctx. */
int rs_body_outside(spx_ctx *ctx, const spx_body_model *m, const spx_mesh *woman, const spx_image *parts, int k,
                    rs_body *out);
/* Body b of the shipped model's own space (0: at rest, b > 0: synth_body(m, 40 + b, 0.3)). */
int rs_body_inside(spx_ctx *ctx, const spx_body_model *m, int b, rs_body *out);
void rs_body_free(rs_body *b);

/* The depth image (cam->height*cam->width metres, 0 = no data) of the body through cam; room: with
 * the floor and walls. seed: the noise and the flying pixels. Returns 0 or -1 (reason on ctx). */
int rs_depth_frame(spx_ctx *ctx, const rs_body *b, const spx_camera *cam, int room, uint64_t seed, float *depth);

/* A camera at `dist` metres from the body's bounding-box centre at azimuth az (radians, 0 = in
 * front, +z) and height `up` metres above that centre, looking at it; K of a real 640x480 sensor
 * (f = 525 px, principal point (319.5, 239.5)) scaled to W x H. */
int rs_camera(spx_ctx *ctx, const rs_body *b, double az, double up, double dist, int32_t W, int32_t H,
              spx_camera *cam);

#endif
