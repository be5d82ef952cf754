/* Framing (lib/render/frame.c, spx_camera_frame / spx_camera_bbox): for a standing "person" of
 * random points, from many directions, portrait and landscape sizes and several fills, the points
 * projected with the camera's K, R, t (computed here, plainly) have a bounding box that fills `fill`
 * of the limiting dimension and fits the other, centred; the eye sits at the distance asked for
 * (default: SPX_FRAME_DISTANCE x the largest side) and looks at the box's centre; spx_camera_bbox
 * equals the plain box; and the errors. */
#include "test.h"

#include "smplpix/camera.h"

static spx_ctx *ctx;

static uint64_t rng_state = 0x2545F4914F6CDD1DULL;
static double urand(void) {
  rng_state ^= rng_state << 13, rng_state ^= rng_state >> 7, rng_state ^= rng_state << 17;
  return (double)(rng_state >> 11) / 9007199254740992.0;
}

/* A box-shaped figure 1.7 tall, 0.5 wide, 0.3 deep, standing on y = 0.1, off the origin; arms out
 * to +-0.8 when `arms`. */
static float *figure(int n, int arms) {
  float *p = malloc(sizeof(float) * 3 * (size_t)n);
  for (int i = 0; i < n; i++) {
    double w = arms && i % 5 == 0 ? 1.6 : 0.5;
    p[3 * i] = (float)(0.3 + (urand() - 0.5) * w);
    p[3 * i + 1] = (float)(0.1 + urand() * 1.7);
    p[3 * i + 2] = (float)(-0.2 + (urand() - 0.5) * 0.3);
  }
  return p;
}

/* The pixel box of the points through cam: u = (K (R p + t))_0 / d, v likewise. */
static void plain_box(const spx_camera *c, int n, const float *p, double b[4]) {
  b[0] = b[1] = INFINITY, b[2] = b[3] = -INFINITY;
  for (int i = 0; i < n; i++) {
    double q[3], k[3];
    for (int r = 0; r < 3; r++) q[r] = c->R[r][0] * p[3 * i] + c->R[r][1] * p[3 * i + 1] + c->R[r][2] * p[3 * i + 2] + c->t[r];
    for (int r = 0; r < 3; r++) k[r] = c->K[r][0] * q[0] + c->K[r][1] * q[1] + c->K[r][2] * q[2];
    double u = k[0] / k[2], v = k[1] / k[2];
    b[0] = fmin(b[0], u), b[1] = fmin(b[1], v), b[2] = fmax(b[2], u), b[3] = fmax(b[3], v);
  }
}

static void test_fills(void) {
  const int n = 3000, sizes[3][2] = {{192, 256}, {256, 192}, {64, 48}};
  const double fills[3] = {0.9, 0.84, 1.0}, pi = 3.14159265358979323846;
  for (int arms = 0; arms < 2; arms++) {
    float *p = figure(n, arms);
    for (int s = 0; s < 3; s++)
      for (int k = 0; k < 12; k++) {
        int W = sizes[s][0], H = sizes[s][1];
        double az = 2 * pi * k / 12, el = (-10 + 45.0 * k / 11) * pi / 180, fill = fills[k % 3];
        double dist = k % 4 == 0 ? 0 : 2.5 + k * 0.3;
        spx_camera c;
        CHECK_OK(ctx, spx_camera_frame(ctx, n, p, W, H, az, el, dist, fill, &c));
        CHECK_OK(ctx, spx_camera_validate(ctx, "frame", &c));
        double b[4], lb[4];
        plain_box(&c, n, p, b);
        CHECK_OK(ctx, spx_camera_bbox(ctx, &c, n, p, lb));
        for (int q = 0; q < 4; q++) CHECK_NEAR(lb[q], b[q], 1e-9, 0);
        double fw = (b[2] - b[0]) / W, fh = (b[3] - b[1]) / H;
        CHECK_MSG(fabs(fmax(fw, fh) - fill) < 1e-9 && fw <= fill + 1e-9 && fh <= fill + 1e-9,
                  "size %dx%d view %d arms %d: box fills %.6f x %.6f, fill %.3f", W, H, k, arms, fw, fh, fill);
        CHECK_NEAR(0.5 * (b[0] + b[2]), 0.5 * W, 1e-6, 0);
        CHECK_NEAR(0.5 * (b[1] + b[3]), 0.5 * H, 1e-6, 0);
        CHECK(c.K[0][0] == c.K[1][1] && c.K[0][1] == 0);
        /* the eye: at dist (default 2 x the 1.7 largest side) from the box centre, looking at it */
        double eye[3], ctr[3] = {0, 0, 0}, lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int i = 0; i < 3 * n; i++) lo[i % 3] = fmin(lo[i % 3], p[i]), hi[i % 3] = fmax(hi[i % 3], p[i]);
        for (int r = 0; r < 3; r++) ctr[r] = 0.5 * (lo[r] + hi[r]);
        for (int r = 0; r < 3; r++) eye[r] = -(c.R[0][r] * c.t[0] + c.R[1][r] * c.t[1] + c.R[2][r] * c.t[2]);
        double d2 = 0, side = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
        for (int r = 0; r < 3; r++) d2 += (eye[r] - ctr[r]) * (eye[r] - ctr[r]);
        CHECK_NEAR(sqrt(d2), dist > 0 ? dist : SPX_FRAME_DISTANCE * side, 1e-6, 1e-9);
        double fwd[3] = {ctr[0] - eye[0], ctr[1] - eye[1], ctr[2] - eye[2]}, dot = 0;
        for (int r = 0; r < 3; r++) dot += c.R[2][r] * fwd[r] / sqrt(d2);
        CHECK_NEAR(dot, 1, 1e-9, 0);
        CHECK_NEAR(asin(-fwd[1] / sqrt(d2)), el, 1e-9, 0);
      }
    /* standing, no arms, portrait: the height is the limit */
    spx_camera c;
    CHECK_OK(ctx, spx_camera_frame(ctx, n, p, 192, 256, 0.3, 0.1, 0, SPX_FRAME_FILL, &c));
    double b[4];
    plain_box(&c, n, p, b);
    if (!arms) CHECK_NEAR((b[3] - b[1]) / 256, SPX_FRAME_FILL, 1e-9, 0);
    free(p);
  }
}

static void test_errors(void) {
  float *p = figure(100, 0);
  spx_camera c;
  CHECK(spx_camera_frame(ctx, 100, p, 192, 256, 0, 0, 0, 0, &c) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "fill") != NULL);
  CHECK(spx_camera_frame(ctx, 100, p, 192, 256, 0, 0, 0, 1.2, &c) == SPX_E_ARG);
  CHECK(spx_camera_frame(ctx, 0, p, 192, 256, 0, 0, 0, 0.9, &c) == SPX_E_ARG);
  CHECK(spx_camera_frame(ctx, 100, p, 0, 256, 0, 0, 0, 0.9, &c) == SPX_E_ARG);
  CHECK(spx_camera_frame(ctx, 100, p, 192, 256, 0, 1.6, 0, 0.9, &c) == SPX_E_ARG); /* straight down */
  CHECK(spx_camera_frame(ctx, 100, p, 192, 256, 0, 0, 0.1, 0.9, &c) == SPX_E_ARG);  /* inside the figure */
  CHECK(strstr(spx_ctx_message(ctx), "in front of the camera") != NULL);
  float one[6] = {1, 2, 3, 1, 2, 3};
  CHECK(spx_camera_frame(ctx, 2, one, 192, 256, 0, 0, 0, 0.9, &c) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "extent") != NULL);
  p[7] = NAN;
  CHECK(spx_camera_frame(ctx, 100, p, 192, 256, 0, 0, 0, 0.9, &c) == SPX_E_NUMERIC);
  free(p);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_fills), SPX_TEST(test_errors)};
  return spx_t_main_ctx(&ctx, 0, tests, 2);
}
