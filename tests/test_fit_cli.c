/* Registration inputs, outputs and the register / repose / reshape subcommands: bad scans and
 * models give one-line errors naming the file, exit 1 and no output; parameters survive a JSON
 * round trip; colours are transferred from a coloured scan; repose and reshape pose the person. */
#include <sys/stat.h>

#include "fit_synth.h"
#include "smplpix/npz.h"
#include "test.h"

static spx_ctx *ctx;
static spx_body_model model;

static void write_text(const char *path, const char *text) {
  FILE *f = fopen(path, "wb");
  if (!f) return;
  fputs(text, f);
  fclose(f);
}

static char *read_text(const char *path) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char *buf = calloc(1, 65536);
  if (buf) fread(buf, 1, 65535, f);
  fclose(f);
  return buf;
}

/* exit status of the tool; stderr into err (one string) */
static int run_tool(const char *args, char *err, size_t cap) {
  char cmd[9000], errpath[512];
  spx_t_path(errpath, sizeof errpath, "stderr.txt");
  snprintf(cmd, sizeof cmd, "'%s' %s >/dev/null 2>'%s'", spx_t_tool(), args, errpath);
  int rc = spx_t_system(cmd);
  char *e = read_text(errpath);
  snprintf(err, cap, "%s", e ? e : "");
  free(e);
  return rc;
}

static int count_lines(const char *s) {
  int n = 0;
  for (; *s; s++) n += *s == '\n';
  return n;
}

static void synth_default_scan(uint64_t seed, int32_t npts, int colors, spx_mesh *scan, double *V, double R[9],
                               double t[3]) {
  CHECK_OK(ctx, synth_posed(ctx, &model, seed, 0.2, V));
  synth_opts so = {npts, 0.001, 0.0, 1, 1.0, colors};
  CHECK(synth_scan(V, model.nv, model.faces, model.nf, &so, seed, scan, R, t) == 0);
}

static void test_api_bad_inputs(void) {
  spx_fit_result r;
  spx_mesh empty = {0};
  CHECK(spx_fit_register(ctx, &model, &empty, NULL, &r) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "points") != NULL);
  float pts[30 * 3];
  for (int i = 0; i < 90; i++) pts[i] = (float)(i % 7) * 0.1f;
  pts[40] = NAN;
  spx_mesh bad = {0};
  bad.nv = 30, bad.pos = pts;
  CHECK(spx_fit_register(ctx, &model, &bad, NULL, &r) == SPX_E_NUMERIC);
  CHECK(strstr(spx_ctx_message(ctx), "not finite") != NULL);
  for (int i = 0; i < 90; i++) pts[i] = 0.5f;
  CHECK(spx_fit_register(ctx, &model, &bad, NULL, &r) == SPX_E_ARG); /* no extent */
  CHECK(r.verts_scan == NULL && r.pose == NULL);
  spx_fit_options o;
  spx_fit_options_default(&o);
  o.stages = 0;
  pts[0] = 0;
  CHECK(spx_fit_register(ctx, &model, &bad, &o, &r) == SPX_E_ARG);
}

static void test_json_and_colors(void) {
  double *V = malloc((size_t)model.nv * 3 * sizeof(double)), R[9], t[3];
  spx_mesh scan;
  synth_default_scan(21, 10000, 1, &scan, V, R, t);
  spx_fit_options o;
  spx_fit_options_default(&o);
  o.stages = SPX_FIT_RIGID | SPX_FIT_POSE;
  o.pose_steps = 12;
  spx_fit_result r, back;
  CHECK_OK(ctx, spx_fit_register(ctx, &model, &scan, &o, &r));
  CHECK(r.colors != NULL);
  /* colours: the synthetic colour field (a function of the body-frame position) at the true vertices */
  double ce = 0;
  for (int32_t i = 0; r.colors && i < r.nv; i++)
    for (int d = 0; d < 3; d++) ce += fabs(r.colors[i * 3 + d] - (0.5 + 0.5 * sin(7.0 * V[i * 3 + (d + 1) % 3] + d)));
  ce /= 3.0 * r.nv;
  fprintf(stderr, "  colour transfer: mean abs error %.4f\n", ce);
  CHECK(ce < 0.03);
  char path[1024];
  spx_t_path(path, sizeof path, "params.json");
  CHECK_OK(ctx, spx_fit_save_json(ctx, path, &r, "some/model.npz"));
  char *mp = NULL;
  CHECK_OK(ctx, spx_fit_load_json(ctx, path, &back, &mp));
  CHECK(mp && !strcmp(mp, "some/model.npz"));
  free(mp);
  CHECK(back.nv == r.nv && back.nj == r.nj && back.nbetas == r.nbetas);
  double worst = 0;
  for (int32_t i = 0; i < r.nj * 3; i++) worst = fmax(worst, fabs(back.pose[i] - r.pose[i]));
  for (int32_t i = 0; i < r.nbetas; i++) worst = fmax(worst, fabs(back.betas[i] - r.betas[i]));
  for (int i = 0; i < 9; i++) worst = fmax(worst, fabs(back.sim_R[i] - r.sim_R[i]));
  for (int i = 0; i < 3; i++) worst = fmax(worst, fabs(back.sim_t[i] - r.sim_t[i]) + fabs(back.trans[i] - r.trans[i]));
  worst = fmax(worst, fabs(back.sim_scale - r.sim_scale) + fabs(back.body_scale - r.body_scale));
  CHECK_MSG(worst < 1e-12, "parameters differ by %g", worst);
  double tw = 0;
  for (int32_t i = 0; back.template_unposed && i < r.nv * 3; i++)
    tw = fmax(tw, fabs(back.template_unposed[i] - r.template_unposed[i]));
  CHECK(back.template_unposed && back.colors && tw < 1e-6);
  spx_fit_result_free(&back);
  /* hostile JSON: wrong format tag, wrong array length */
  write_text(path, "{\"format\": \"other\"}");
  CHECK(spx_fit_load_json(ctx, path, &back, NULL) == SPX_E_FORMAT);
  write_text(path, "{\"format\": \"smplpix-registration\", \"nv\": 3, \"nj\": 1, \"unit_scale\": 1, \"body_scale\": 1,"
                   "\"similarity\": {\"scale\": 1, \"R\": [1,0,0,0,1,0,0,0,1], \"t\": [0,0,0]}, \"betas\": [],"
                   "\"pose\": [0, 0], \"trans\": [0,0,0]}");
  CHECK(spx_fit_load_json(ctx, path, &back, NULL) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "pose") != NULL);
  spx_fit_result_free(&r);
  spx_mesh_free(&scan);
  free(V);
}

static void test_cli(void) {
  char err[8192], args[8192], scan_path[512], out[512], params[512], npz[512], bvh_out[512], rs_out[512];
  if (run_tool("register --help", err, sizeof err) != 0) {
    fprintf(stderr, "  (skipped: `smplpix register` is not in apps/main.c's command table yet)\n");
    return;
  }
  spx_t_path(out, sizeof out, "reg.ply");
  spx_t_path(params, sizeof params, "reg.json");
  remove(out), remove(params);
  /* empty scan */
  spx_t_path(scan_path, sizeof scan_path, "empty.ply");
  write_text(scan_path, "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n");
  snprintf(args, sizeof args, "register --scan '%s' --out '%s' --params '%s'", scan_path, out, params);
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK_MSG(strstr(err, scan_path) && count_lines(err) == 1, "stderr: %s", err);
  CHECK(!spx_t_file_exists(out) && !spx_t_file_exists(params));
  /* NaN point */
  spx_t_path(scan_path, sizeof scan_path, "nan.obj");
  write_text(scan_path, "v 0 0 0\nv 1 0 0\nv nan 1 0\n");
  snprintf(args, sizeof args, "register --scan '%s' --out '%s'", scan_path, out);
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK_MSG(strstr(err, scan_path) && count_lines(err) == 1, "stderr: %s", err);
  CHECK(!spx_t_file_exists(out));
  /* a valid scan for the rest */
  double *V = malloc((size_t)model.nv * 3 * sizeof(double)), R[9], t[3];
  spx_mesh scan;
  synth_default_scan(23, 8000, 1, &scan, V, R, t);
  spx_t_path(scan_path, sizeof scan_path, "scan.ply");
  CHECK_OK(ctx, spx_mesh_save(ctx, scan_path, &scan, SPX_MESH_PLY_BINARY));
  /* a model whose J_regressor does not match its vertex count */
  spx_t_path(npz, sizeof npz, "bad_model.npz");
  {
    float vt[4 * 3] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}, jr[2 * 5] = {0}, wt[4 * 2] = {1, 0, 1, 0, 0, 1, 0, 1};
    float sd[4 * 3 * 1] = {0};
    int32_t f[2 * 3] = {0, 1, 2, 0, 2, 3}, kt[2 * 2] = {-1, 0, 0, 1};
    spx_array a[6] = {{SPX_F32, 2, {4, 3}, vt, sizeof vt},  {SPX_F32, 2, {2, 5}, jr, sizeof jr},
                      {SPX_F32, 2, {4, 2}, wt, sizeof wt},  {SPX_F32, 3, {4, 3, 1}, sd, sizeof sd},
                      {SPX_I32, 2, {2, 3}, f, sizeof f},    {SPX_I32, 2, {2, 2}, kt, sizeof kt}};
    const char *keys[6] = {"v_template", "J_regressor", "weights", "shapedirs", "f", "kintree_table"};
    CHECK_OK(ctx, spx_npz_save(ctx, npz, 6, keys, a, 0));
  }
  snprintf(args, sizeof args, "register --scan '%s' --model '%s' --out '%s' --params '%s'", scan_path, npz, out, params);
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK_MSG(strstr(err, npz) && count_lines(err) == 1, "stderr: %s", err);
  CHECK(!spx_t_file_exists(out) && !spx_t_file_exists(params));
  /* usage errors */
  snprintf(args, sizeof args, "register --scan '%s' --out '%s' --stages rigid,bogus", scan_path, out);
  CHECK(run_tool(args, err, sizeof err) == 2);
  CHECK(run_tool("register --out x.ply", err, sizeof err) == 2);
  /* a real run: rigid + pose (short), then repose and reshape */
  snprintf(args, sizeof args, "register --scan '%s' --out '%s' --params '%s' --stages rigid,pose --threads 2", scan_path,
           out, params);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  spx_mesh reg;
  CHECK_OK(ctx, spx_mesh_load(ctx, out, &reg));
  CHECK(reg.nv == model.nv && reg.nf == model.nf && reg.col != NULL);
  /* the registered mesh overlays the scan */
  double mean = 1;
  CHECK_OK(ctx, spx_fit_surface_distance(ctx, scan.pos, scan.nv, reg.pos, reg.nv, reg.faces, reg.nf, NULL, &mean, NULL, NULL));
  CHECK_MSG(mean < 0.006, "scan -> registration mean %.2f mm", mean * 1e3);
  spx_t_path(bvh_out, sizeof bvh_out, "repose.ply");
  snprintf(args, sizeof args, "repose --registration '%s' --bvh '%s/mocap/01_01.bvh' --frame 100 --out '%s'", params,
           SPX_REPO_DATA, bvh_out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  spx_mesh rp;
  CHECK_OK(ctx, spx_mesh_load(ctx, bvh_out, &rp));
  CHECK(rp.nv == model.nv && rp.col != NULL);
  snprintf(args, sizeof args, "repose --registration '%s' --bvh '%s/mocap/01_01.bvh' --frame 999999 --out '%s'",
           params, SPX_REPO_DATA, bvh_out);
  CHECK(run_tool(args, err, sizeof err) == 1);
  CHECK(count_lines(err) == 1);
  spx_t_path(rs_out, sizeof rs_out, "reshape.ply");
  snprintf(args, sizeof args, "reshape --registration '%s' --shape 0:+2.0 --out '%s' --rest", params, rs_out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  spx_mesh a, b;
  CHECK_OK(ctx, spx_mesh_load(ctx, rs_out, &a));
  snprintf(args, sizeof args, "reshape --registration '%s' --shape 0:+0 --out '%s' --rest", params, rs_out);
  CHECK_MSG(run_tool(args, err, sizeof err) == 0, "stderr: %s", err);
  CHECK_OK(ctx, spx_mesh_load(ctx, rs_out, &b));
  /* shape direction 0 changes the body: the meshes differ by centimetres, not micrometres */
  double dmax = 0;
  for (int32_t i = 0; i < a.nv * 3 && a.nv == b.nv; i++) dmax = fmax(dmax, fabs(a.pos[i] - b.pos[i]));
  CHECK_MSG(dmax > 0.01, "reshape moved vertices by at most %g m", dmax);
  snprintf(args, sizeof args, "reshape --registration '%s' --shape 99:1 --out '%s'", params, rs_out);
  CHECK(run_tool(args, err, sizeof err) == 1);
  spx_mesh_free(&a), spx_mesh_free(&b), spx_mesh_free(&rp), spx_mesh_free(&reg), spx_mesh_free(&scan);
  free(V);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_api_bad_inputs), SPX_TEST(test_json_and_colors), SPX_TEST(test_cli)};
  return spx_t_main_body(&ctx, &model, tests, (int)(sizeof tests / sizeof tests[0]));
}
