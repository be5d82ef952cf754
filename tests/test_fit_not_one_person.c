/* `smplpix register` refuses a fit whose residual says much of the input is not the body: a scan of
 * a posed body standing on 2.4 x 2.4 m of floor (as a raw scanner capture holds it) is one line,
 * exit 1, naming the share of the scan far from the fitted body, and nothing is written; the same
 * body without the floor registers. */
#include "fit_view.h"
#include "test.h"

static spx_ctx *ctx;
static spx_body_model model;

static int run_tool(const char *args, char *err, size_t cap) {
  char cmd[4096], errpath[512];
  spx_t_path(errpath, sizeof errpath, "stderr.txt");
  snprintf(cmd, sizeof cmd, "'%s' %s >/dev/null 2>'%s'", spx_t_tool(), args, errpath);
  int rc = spx_t_system(cmd);
  FILE *f = fopen(errpath, "rb");
  size_t n = f ? fread(err, 1, cap - 1, f) : 0;
  err[n] = 0;
  if (f) fclose(f);
  return rc;
}

static void test_floor_refused(void) {
  double *V = malloc((size_t)model.nv * 3 * sizeof(double));
  CHECK_OK(ctx, synth_posed(ctx, &model, 49, 0.25, V));
  spx_mesh body;
  synth_opts so = {8000, 0.002, 0.0, 0, 1.0, 0};
  CHECK(synth_scan(V, model.nv, model.faces, model.nf, &so, 3, &body, NULL, NULL) == 0);
  double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30};
  for (int32_t i = 0; i < model.nv; i++)
    for (int d = 0; d < 3; d++) lo[d] = fmin(lo[d], V[i * 3 + d]), hi[d] = fmax(hi[d], V[i * 3 + d]);
  enum { G = 60 }; /* 60 x 60 floor points, 4 cm apart */
  spx_mesh scan = {0};
  scan.nv = body.nv + G * G;
  scan.pos = malloc((size_t)scan.nv * 3 * sizeof(float));
  memcpy(scan.pos, body.pos, (size_t)body.nv * 3 * sizeof(float));
  for (int k = 0; k < G * G; k++) {
    float *p = scan.pos + (size_t)(body.nv + k) * 3;
    p[0] = (float)(0.5 * (lo[0] + hi[0]) - 1.2 + 0.04 * (k % G)), p[1] = (float)lo[1];
    p[2] = (float)(0.5 * (lo[2] + hi[2]) - 1.2 + 0.04 * (k / G));
  }
  char scanp[512], bodyp[512], out[512], args[2048], err[4096];
  spx_t_path(scanp, sizeof scanp, "floor.ply");
  spx_t_path(bodyp, sizeof bodyp, "body.ply");
  spx_t_path(out, sizeof out, "reg.ply");
  CHECK_OK(ctx, spx_mesh_save(ctx, scanp, &scan, SPX_MESH_PLY_BINARY));
  CHECK_OK(ctx, spx_mesh_save(ctx, bodyp, &body, SPX_MESH_PLY_BINARY));
  remove(out);
  snprintf(args, sizeof args, "register --scan '%s' --out '%s' --stages rigid,pose --threads 2", scanp, out);
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK_MSG(strstr(err, scanp) && strstr(err, "of the scan's points are more than 5 cm from the fitted body") &&
                strchr(err, '\n') == err + strlen(err) - 1,
            "stderr: %s", err);
  CHECK(!spx_t_file_exists(out));
  snprintf(args, sizeof args, "register --scan '%s' --out '%s' --stages rigid,pose --threads 2", bodyp, out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  CHECK(spx_t_file_exists(out));
  spx_mesh_free(&scan), spx_mesh_free(&body);
  free(V);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_floor_refused)};
  return spx_t_main_body(&ctx, &model, tests, (int)(sizeof tests / sizeof tests[0]));
}
