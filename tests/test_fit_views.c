/* Registration from what one depth camera sees (tests/fit_view.h), scored against the complete
 * surface of the body:
 *  - spx_fit_depth_points: pixel centres and camera depth back-project exactly; a depth image
 *    rendered by the rasterizer (its depth channel) lands on the true surface; NaN and inf are no
 *    data; bad depth (negative, none, a size that is not the camera's) is refused;
 *  - single-view scans (front, side, back, from above) of the shipped body and of a posed,
 *    reshaped body, registered with the camera's position, land within 2 mm of the complete
 *    surface and within twice the full scan's error; so does a front scan without the camera (the
 *    fit finds the side it was seen from); a rendered depth image registers like the single-view
 *    scans;
 *  - a front view of the shipped body far outside its shape range registers within 2.5 mm, and a
 *    back view fitted the wrong way round within 2 mm: the pose stage's second starts
 *    (SPX_FIT_AID_RESTART: straight joints; turned round) recover what the first start lost. */
#include "fit_view.h"
#include "test.h"

static spx_ctx *ctx;
static spx_body_model model;

static void test_depth_points_exact(void) {
  spx_camera cam;
  double eye[3] = {0.3, 1.2, 2.5}, target[3] = {0, 0.9, 0}, up[3] = {0, 1, 0};
  CHECK_OK(ctx, spx_camera_look_at(ctx, 40, 30, 37.5, eye, target, up, &cam));
  cam.K[0][1] = 0.7; /* skew, to check the full inverse of K */
  float depth[30 * 40], rgb[30 * 40 * 3];
  for (int p = 0; p < 30 * 40; p++) {
    depth[p] = (p % 7 == 0) ? 0.0f : 1.5f + 0.01f * (float)(p % 13);
    for (int c = 0; c < 3; c++) rgb[p * 3 + c] = (float)(p * 3 + c) / 3600.0f;
  }
  spx_mesh pts;
  CHECK_OK(ctx, spx_fit_depth_points(ctx, "d", &cam, depth, 40, 30, rgb, &pts));
  int32_t k = 0;
  double worst = 0, dworst = 0, cworst = 0;
  for (int p = 0; p < 30 * 40 && k < pts.nv; p++) {
    if (depth[p] == 0) continue;
    const float *x = pts.pos + k * 3;
    double c[3];
    for (int r = 0; r < 3; r++) c[r] = cam.R[r][0] * x[0] + cam.R[r][1] * x[1] + cam.R[r][2] * x[2] + cam.t[r];
    double u = (cam.K[0][0] * c[0] + cam.K[0][1] * c[1] + cam.K[0][2] * c[2]) / c[2];
    double v = (cam.K[1][1] * c[1] + cam.K[1][2] * c[2]) / c[2];
    worst = fmax(worst, fmax(fabs(u - (p % 40 + 0.5)), fabs(v - (p / 40 + 0.5)))); /* pixels */
    dworst = fmax(dworst, fabs(c[2] - depth[p]));                                  /* metres */
    for (int d = 0; d < 3; d++) cworst = fmax(cworst, fabs(pts.col[k * 3 + d] - rgb[p * 3 + d]));
    k++;
  }
  CHECK(k == pts.nv && pts.nv == 30 * 40 - (30 * 40 + 6) / 7);
  CHECK_MSG(worst < 1e-3 && dworst < 1e-5, "back-projection off by %g px, %g m", worst, dworst);
  CHECK(cworst == 0);
  double e[3];
  spx_fit_camera_eye(&cam, e);
  CHECK(fabs(e[0] - eye[0]) + fabs(e[1] - eye[1]) + fabs(e[2] - eye[2]) < 1e-9);
  spx_mesh_free(&pts);
  /* NaN and +inf are no data, as 0 */
  depth[5] = NAN, depth[6] = INFINITY;
  CHECK_OK(ctx, spx_fit_depth_points(ctx, "d.npy", &cam, depth, 40, 30, NULL, &pts));
  CHECK(pts.nv == 30 * 40 - (30 * 40 + 6) / 7 - 2);
  spx_mesh_free(&pts);
  /* bad depth: one message naming the image, no points */
  depth[5] = -0.5f;
  CHECK(spx_fit_depth_points(ctx, "d.npy", &cam, depth, 40, 30, NULL, &pts) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "d.npy") && strstr(spx_ctx_message(ctx), "(5, 0)") && pts.pos == NULL);
  CHECK(strstr(spx_ctx_message(ctx), "negative") != NULL);
  depth[5] = 1;
  CHECK(spx_fit_depth_points(ctx, "d.npy", &cam, depth, 30, 40, NULL, &pts) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "30x40") != NULL);
  memset(depth, 0, sizeof depth);
  CHECK(spx_fit_depth_points(ctx, "d.npy", &cam, depth, 40, 30, NULL, &pts) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "no pixel has depth") != NULL);
}

/* the rasterizer's depth channel, back-projected at the pixel centres, lies on the surface */
static void test_raster_depth_on_surface(void) {
  double *V = malloc((size_t)model.nv * 3 * sizeof(double));
  for (int32_t i = 0; i < model.nv * 3; i++) V[i] = model.v_template[i];
  spx_camera cam;
  double dir[3] = {0.3, 0.2, 1};
  CHECK(view_camera(ctx, V, model.nv, dir, 2.4, 320, 240, 262.5, &cam) == 0);
  float *depth = malloc(320 * 240 * sizeof(float));
  CHECK(view_depth(ctx, V, model.nv, model.faces, model.nf, &cam, depth) == 0);
  spx_mesh pts;
  CHECK_OK(ctx, spx_fit_depth_points(ctx, "raster", &cam, depth, 320, 240, NULL, &pts));
  float *Vf = malloc((size_t)model.nv * 3 * sizeof(float));
  for (int32_t i = 0; i < model.nv * 3; i++) Vf[i] = (float)V[i];
  double mean = 1, p95 = 1;
  CHECK_OK(ctx, spx_fit_surface_distance(ctx, pts.pos, pts.nv, Vf, model.nv, model.faces, model.nf, NULL, &mean, NULL, &p95));
  fprintf(stderr, "  rendered depth: %d points, surface distance mean %.4f mm, p95 %.4f mm\n", pts.nv, mean * 1e3,
          p95 * 1e3);
  CHECK(pts.nv > 4000);
  CHECK_MSG(mean < 1e-4 && p95 < 3e-4, "mean %.3g m", mean);
  spx_mesh_free(&pts);
  free(V), free(depth), free(Vf);
}

/* Registers scan; returns the complete-surface error of the result (metres) or 1 on failure. */
static double register_score_steps(const double *V, const spx_mesh *scan, const spx_camera *cam, int pose_steps,
                                   int free_steps) {
  spx_fit_options o;
  spx_fit_options_default(&o);
  o.threads = 2;
  o.pose_steps = pose_steps;
  o.free_steps = free_steps;
  if (cam) o.view = 1, spx_fit_camera_eye(cam, o.view_eye);
  spx_fit_result r;
  if (spx_fit_register(ctx, &model, scan, &o, &r)) {
    fprintf(stderr, "  registration failed: %s\n", spx_ctx_message(ctx));
    return 1;
  }
  double e = view_complete_error(ctx, V, model.nv, model.faces, model.nf, r.verts_scan, r.nv, r.faces, r.nf);
  spx_fit_result_free(&r);
  return e;
}

static double register_score(const double *V, const spx_mesh *scan, const spx_camera *cam) {
  return register_score_steps(V, scan, cam, 14, 2);
}

static void test_single_views(void) {
  static const char *names[4] = {"front", "side", "back", "above"};
  static const double dirs[4][3] = {{0, 0, 1}, {1, 0, 0}, {0, 0, -1}, {0, 1.2, 1}};
  double *V = malloc((size_t)model.nv * 3 * sizeof(double));
  double *pose = calloc((size_t)model.nj * 3, sizeof(double)), *betas = calloc((size_t)model.nbetas, sizeof(double));
  for (int b = 0; b < 2; b++) {
    double trans[3] = {0, 0, 0};
    if (b) synth_body(&model, 41, 0.3, pose, betas, trans);
    spx_body_params p = {model.nbetas, betas, pose, trans, NULL};
    CHECK_OK(ctx, spx_body_forward_ref(ctx, &model, &p, V, NULL));
    spx_mesh full;
    synth_opts so = {12000, 0.002, 0.0, 0, 1.0, 0};
    CHECK(synth_scan(V, model.nv, model.faces, model.nf, &so, 5, &full, NULL, NULL) == 0);
    double ef = register_score(V, &full, NULL);
    fprintf(stderr, "  body %d full scan: %.2f mm from the complete surface\n", b, ef * 1e3);
    CHECK(ef < 0.002);
    spx_mesh_free(&full);
    for (int v = b ? 0 : 3; v < 4; v++) { /* the shipped body: from above; the posed one: all four */
      spx_camera cam;
      spx_mesh scan;
      CHECK(view_camera(ctx, V, model.nv, dirs[v], 2.4, 640, 480, 525, &cam) == 0);
      CHECK(view_scan(ctx, V, model.nv, model.faces, model.nf, &cam, 24000, 0.002, 6 + v, &scan) == 0);
      double e = register_score(V, &scan, &cam);
      fprintf(stderr, "  body %d %-5s view (%d points): %.2f mm from the complete surface\n", b, names[v], scan.nv,
              e * 1e3);
      CHECK_MSG(e < 0.002 && e < 2 * ef, "%s: %.2f mm", names[v], e * 1e3);
      if (b && v == 0) {
        double en = register_score(V, &scan, NULL);
        fprintf(stderr, "  body %d front view without the camera: %.2f mm\n", b, en * 1e3);
        CHECK_MSG(en < 0.002 && en < 2 * ef, "%.2f mm", en * 1e3);
      }
      spx_mesh_free(&scan);
    }
  }
  free(V), free(pose), free(betas);
}

/* a 320x240 depth image of a posed body, in whole millimetres, back-projected and registered */
static void test_depth_image(void) {
  double *V = malloc((size_t)model.nv * 3 * sizeof(double));
  CHECK_OK(ctx, synth_posed(ctx, &model, 43, 0.3, V));
  spx_camera cam;
  double dir[3] = {0.2, 0.15, 1};
  CHECK(view_camera(ctx, V, model.nv, dir, 2.4, 320, 240, 262.5, &cam) == 0);
  float *depth = malloc(320 * 240 * sizeof(float));
  CHECK(view_depth(ctx, V, model.nv, model.faces, model.nf, &cam, depth) == 0);
  for (int i = 0; i < 320 * 240; i++) depth[i] = roundf(depth[i] * 1000.0f) / 1000.0f;
  spx_mesh scan;
  CHECK_OK(ctx, spx_fit_depth_points(ctx, "depth", &cam, depth, 320, 240, NULL, &scan));
  double e = register_score(V, &scan, &cam);
  fprintf(stderr, "  320x240 depth image (%d points): %.2f mm from the complete surface\n", scan.nv, e * 1e3);
  CHECK_MSG(e < 0.0025, "%.2f mm", e * 1e3);
  spx_mesh_free(&scan);
  free(V), free(depth);
}

/* The complete-surface error (metres) of a view of synth_body(seed) from direction dir (2.4 m),
 * its shape coefficients 1-9 at +-4 when far; n samples of the view, the registration's default
 * steps when full. */
static double view_case(uint64_t seed, int far, const double dir[3], int n, int full) {
  double *V = malloc((size_t)model.nv * 3 * sizeof(double));
  double *pose = calloc((size_t)model.nj * 3, sizeof(double)), *betas = calloc((size_t)model.nbetas, sizeof(double));
  double trans[3] = {0, 0, 0}, e = 1;
  synth_body(&model, seed, 0.3, pose, betas, trans);
  for (int32_t i = 0; far && i < model.nbetas; i++) betas[i] = i == 0 ? 0.5 : i % 2 ? 4.0 : -4.0;
  spx_body_params p = {model.nbetas, betas, pose, trans, NULL};
  spx_camera cam;
  spx_mesh scan = {0};
  if (!spx_body_forward_ref(ctx, &model, &p, V, NULL) &&
      !view_camera(ctx, V, model.nv, dir, 2.4, 640, 480, 525, &cam) &&
      !view_scan(ctx, V, model.nv, model.faces, model.nf, &cam, n, 0.002, 11, &scan))
    e = full ? register_score_steps(V, &scan, &cam, 20, 4) : register_score(V, &scan, &cam);
  spx_mesh_free(&scan);
  free(V), free(pose), free(betas);
  return e;
}

/* The shipped body far outside its shape range (coefficients 1-9 at +-4), posed, seen from the
 * front a little to its right: fitted from the mean shape, a part of the body is drawn away from
 * its scan points early and stays beyond the pairs' reach (8.8 mm from the complete surface
 * without the second starts); the start from the fitted shape with straight joints finds it. */
static void test_far_shape_second_start(void) {
  double dir[3] = {sin(-0.3), 0, cos(-0.3)};
  double e = view_case(63, 1, dir, 24000, 0);
  fprintf(stderr, "  shape coefficients at +-4, front view: %.2f mm from the complete surface\n", e * 1e3);
  CHECK_MSG(e < 0.0025, "%.2f mm", e * 1e3);
}

/* A posed body of the model's own space seen from behind, as the benchmark scans it (100k samples,
 * the default steps): the rigid stage's two orientations score within 7% of each other and the
 * first start ends the wrong way round (9.7 mm without the turned start); the start with the root
 * turned round finds the back. */
static void test_back_view_turned_start(void) {
  double dir[3] = {0, 0, -1};
  double e = view_case(42, 0, dir, 100000, 1);
  fprintf(stderr, "  back view: %.2f mm from the complete surface\n", e * 1e3);
  CHECK_MSG(e < 0.002, "%.2f mm", e * 1e3);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_depth_points_exact), SPX_TEST(test_raster_depth_on_surface),
                                     SPX_TEST(test_depth_image), SPX_TEST(test_single_views),
                                     SPX_TEST(test_far_shape_second_start), SPX_TEST(test_back_view_turned_start)};
  return spx_t_main_body(&ctx, &model, tests, (int)(sizeof tests / sizeof tests[0]));
}
