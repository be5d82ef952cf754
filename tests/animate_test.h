/* Shared by the animate / render end-to-end tests (tests/test_cli_animate*.c): a registration of
 * the default body written through the library, cameras framing a posed body, the library's own
 * rendering of a posed frame (the reference the tool must match), and a runner with an environment
 * prefix. Needs cli_test.h (dir) and a global `spx_ctx *ctx`. */
#ifndef SPX_TESTS_ANIMATE_TEST_H
#define SPX_TESTS_ANIMATE_TEST_H

#include "cli_test.h"
#include "smplpix/smplpix.h"

#define BODY SPX_REPO_DATA "/body/default_body.npz"
#define CLIP SPX_REPO_DATA "/mocap/01_01.bvh"
enum { CW = 48, CH = 64 }; /* small camera: the frames render in milliseconds */

static spx_ctx *ctx;
static spx_body_model body;
static spx_fit_result reg; /* write_registration's file read back (the tool sees the same numbers) */

/* `env` (may be "") then the tool with args, in dir; output to out.txt / err.txt */
static int tool_env(const char *env, const char *args) {
  char cmd[4096];
  snprintf(cmd, sizeof cmd, "cd '%s' && %s '%s' %s >out.txt 2>err.txt", dir, env, spx_t_tool(), args);
  return spx_t_system(cmd);
}

static int file_has(const char *name, const char *needle) {
  char p[700], buf[8192] = "";
  path_of(p, sizeof p, name);
  FILE *f = fopen(p, "rb");
  if (!f) return 0;
  size_t n = fread(buf, 1, sizeof buf - 1, f);
  fclose(f);
  buf[n] = 0;
  if (!strstr(buf, needle)) fprintf(stderr, "  %s was: %s\n", name, buf);
  return strstr(buf, needle) != NULL;
}

/* reg.json: the default body at rest, coloured by height, with the model path recorded */
static void write_registration(const char *name) {
  spx_fit_result r;
  memset(&r, 0, sizeof r);
  r.nv = body.nv, r.nj = body.nj, r.nbetas = 0, r.nf = body.nf;
  r.unit_scale = r.sim_scale = r.body_scale = 1.0;
  r.sim_R[0] = r.sim_R[4] = r.sim_R[8] = 1.0;
  double betas[1] = {0};
  r.betas = betas;
  r.pose = calloc((size_t)body.nj * 3, sizeof(double));
  r.template_unposed = malloc((size_t)body.nv * 3 * sizeof(double));
  r.colors = malloc((size_t)body.nv * 3 * sizeof(float));
  if (!r.pose || !r.template_unposed || !r.colors) return;
  for (int i = 0; i < body.nv; i++)
    for (int c = 0; c < 3; c++) {
      float y = body.v_template[i * 3 + 1], x = body.v_template[i * 3];
      r.template_unposed[i * 3 + c] = body.v_template[i * 3 + c];
      r.colors[i * 3 + c] = c == 0 ? 0.5f + 0.5f * y : c == 1 ? 0.5f + x : 0.3f;
    }
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_fit_save_json(ctx, p, &r, BODY));
  free(r.pose), free(r.template_unposed), free(r.colors);
  CHECK_OK(ctx, spx_fit_load_json(ctx, p, &reg, NULL));
}

/* posed vertices of the registration (as written by write_registration) for a model pose */
static void posed_verts(const double *pose, const double *trans, float *pos) {
  double *v = malloc((size_t)body.nv * 3 * sizeof(double));
  if (!v) return;
  spx_body_params p = {0, NULL, pose, trans, reg.template_unposed};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &body, &p, v, NULL));
  for (int i = 0; i < body.nv * 3; i++) pos[i] = (float)v[i];
  free(v);
}

/* a CW x CH camera 3 m in front (+z) of the centroid of pos, looking at it */
static void camera_for(const float *pos, const char *name, int count) {
  double c[3] = {0, 0, 0};
  for (int i = 0; i < body.nv * 3; i++) c[i % 3] += pos[i] / body.nv;
  double eye[3] = {c[0], c[1], c[2] + 3.0}, up[3] = {0, 1, 0};
  spx_camera cams[2];
  CHECK_OK(ctx, spx_camera_look_at(ctx, CW, CH, 70.0, eye, c, up, &cams[0]));
  cams[1] = cams[0];
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_camera_save(ctx, p, cams, count));
}

/* What frame `name` (a PNG the tool wrote) must hold: the projection of pos through the camera in
 * cam_name, through net (or raw when NULL), 8-bit rounded. Returns the largest difference. */
static double frame_diff(const char *name, const float *pos, const char *cam_name, spx_unet *net, long *drawn) {
  char p[700];
  spx_camera *cams = NULL;
  int n = 0;
  path_of(p, sizeof p, cam_name);
  CHECK_OK(ctx, spx_camera_load(ctx, p, &cams, &n));
  if (!cams) return 1e9;
  const float *col = reg.colors;
  float *img = malloc(4 * CW * CH * sizeof(float));
  float *out = malloc(3 * CW * CH * sizeof(float));
  spx_projector *proj = NULL;
  double worst = 1e9;
  spx_image got = {0};
  if (!col || !img || !out) goto done;
  CHECK_OK(ctx, spx_projector_create(ctx, &proj));
  spx_project_args a = {1, body.nv, pos, col, 1, cams, SPX_LAYOUT_NCHW};
  CHECK_OK(ctx, spx_project(ctx, proj, &a, img, NULL));
  *drawn = 0;
  for (int i = 0; i < CW * CH; i++) *drawn += img[3 * CW * CH + i] != 1.0f;
  if (net) CHECK_OK(ctx, spx_unet_forward(net, img, 1, CH, CW, 0, out));
  else memcpy(out, img, 3 * CW * CH * sizeof(float));
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_png_read(ctx, p, &got));
  if (got.width != CW || got.height != CH || got.channels != 3) goto done;
  worst = 0;
  for (int c = 0; c < 3; c++)
    for (int q = 0; q < CW * CH; q++) {
      double v = fmin(1.0, fmax(0.0, out[c * CW * CH + q]));
      worst = fmax(worst, fabs(got.data[q * 3 + c] - round(v * 255.0) / 255.0));
    }
done:
  spx_image_free(&got);
  spx_projector_destroy(proj);
  free(cams), free(img), free(out);
  return worst;
}

#endif
