/* Framing a subject as a scanner photo does (smplpix/camera.h, spx_camera_frame; the rule in
 * docs/synth.md): the camera looks at the centre of the points' 3-D bounding box from a direction
 * and a distance; its rotation and position are then fixed, so the points' projected bounding
 * box, in normalised image coordinates (x/z, y/z), is known exactly, and the focal length and the
 * principal point are chosen to scale and centre that box: it fills `fill` of the image height,
 * or of the width when the box is wider than the image allows, with a margin of (1 - fill) / 2 on
 * either side. The framing is exact for the points given, whatever the pose or the perspective. */
#include <math.h>
#include <string.h>

#include "core/internal.h"
#include "smplpix/camera.h"

/* Projected box [u0, v0, u1, v1] of the points through R, t and the intrinsics K (NULL: the
 * normalised coordinates x/z, y/z). Fails when a point is not in front of the camera. */
static spx_status project_box(spx_ctx *ctx, const double R[3][3], const double t[3], const double (*K)[3], int64_t n,
                              const float *pts, double box[4]) {
  box[0] = box[1] = INFINITY, box[2] = box[3] = -INFINITY;
  for (int64_t i = 0; i < n; i++) {
    const float *p = pts + 3 * i;
    double q[3];
    for (int r = 0; r < 3; r++) q[r] = R[r][0] * p[0] + R[r][1] * p[1] + R[r][2] * p[2] + t[r];
    if (!(q[2] > 0))
      return spx_fail(ctx, SPX_E_ARG, "frame: point %lld is not in front of the camera (distance too small)",
                      (long long)i);
    double x = q[0] / q[2], y = q[1] / q[2];
    if (K) {
      double u = K[0][0] * x + K[0][1] * y + K[0][2];
      y = K[1][1] * y + K[1][2];
      x = u;
    }
    box[0] = fmin(box[0], x), box[1] = fmin(box[1], y), box[2] = fmax(box[2], x), box[3] = fmax(box[3], y);
  }
  return SPX_OK;
}

spx_status spx_camera_bbox(spx_ctx *ctx, const spx_camera *cam, int64_t n, const float *pts, double box[4]) {
  if (!cam || !pts || n < 1) return spx_fail(ctx, SPX_E_ARG, "bbox: no points");
  return project_box(ctx, cam->R, cam->t, (const double (*)[3])cam->K, n, pts, box);
}

spx_status spx_camera_frame(spx_ctx *ctx, int64_t n, const float *pts, int32_t width, int32_t height, double az,
                            double el, double dist, double fill, spx_camera *out) {
  if (!pts || n < 1 || !out) return spx_fail(ctx, SPX_E_ARG, "frame: no points");
  if (width < 1 || height < 1 || width > SPX_CAMERA_MAX_SIZE || height > SPX_CAMERA_MAX_SIZE)
    return spx_fail(ctx, SPX_E_ARG, "frame: image size %dx%d out of range", width, height);
  if (!(fill > 0 && fill <= 1)) return spx_fail(ctx, SPX_E_ARG, "frame: fill %g must lie in (0, 1]", fill);
  if (!isfinite(az) || !(fabs(el) < 1.5707963267948966))
    return spx_fail(ctx, SPX_E_ARG, "frame: view direction (azimuth %g, elevation %g rad) must be finite, |elevation| < pi/2",
                    az, el);
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int64_t i = 0; i < 3 * n; i++) {
    if (!isfinite(pts[i])) return spx_fail(ctx, SPX_E_NUMERIC, "frame: point %lld is not finite", (long long)(i / 3));
    lo[i % 3] = fmin(lo[i % 3], pts[i]), hi[i % 3] = fmax(hi[i % 3], pts[i]);
  }
  double c[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
  double side = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
  if (!(side > 0)) return spx_fail(ctx, SPX_E_ARG, "frame: the points have no extent");
  if (!(dist > 0)) dist = SPX_FRAME_DISTANCE * side;
  if (!isfinite(dist)) return spx_fail(ctx, SPX_E_ARG, "frame: distance is not finite");
  const double up[3] = {0, 1, 0};
  double eye[3] = {c[0] + dist * cos(el) * sin(az), c[1] + dist * sin(el), c[2] + dist * cos(el) * cos(az)};
  spx_camera cam;
  spx_status st = spx_camera_look_at(ctx, width, height, 1.0, eye, c, up, &cam);
  if (st) return st;
  double nb[4];
  if ((st = project_box(ctx, cam.R, cam.t, NULL, n, pts, nb))) return st;
  double bw = nb[2] - nb[0], bh = nb[3] - nb[1];
  double f = fmin(bh > 0 ? fill * height / bh : INFINITY, bw > 0 ? fill * width / bw : INFINITY);
  if (!isfinite(f) || !(f > 0)) return spx_fail(ctx, SPX_E_ARG, "frame: the points project to a single point");
  cam.K[0][0] = cam.K[1][1] = f;
  cam.K[0][2] = 0.5 * width - f * 0.5 * (nb[0] + nb[2]);
  cam.K[1][2] = 0.5 * height - f * 0.5 * (nb[1] + nb[3]);
  if ((st = spx_camera_validate(ctx, "frame", &cam))) return st;
  *out = cam;
  return SPX_OK;
}
