/* End to end: `smplpix render --mesh` on point clouds and with the shipped-network default.
 *  - a coloured PLY point cloud (no faces; binary and ASCII) renders through the network on the
 *    device path (projection into a device tensor read by the network) and equals the host path
 *    (spx_project into host memory + spx_unet_forward) bit for bit; a camera array of three goes
 *    through in chunks the same way; a point cloud without colours renders (gray);
 *  - without --checkpoint: data/models/default.safetensors under $SPX_DATA_DIR is used (equal to
 *    naming it), and when it is not there the error is one line naming the path and --checkpoint,
 *    exit 1, no output. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "animate_test.h"

enum { NP = 3000, RW = 40, RH = 36 };

static spx_unet *net;

/* a coloured sphere-ish cloud of NP points, radius 1 */
static void write_cloud(const char *name, spx_mesh_format fmt, int colours) {
  spx_mesh m;
  memset(&m, 0, sizeof m);
  m.nv = NP;
  m.pos = malloc(NP * 3 * sizeof(float));
  m.col = colours ? malloc(NP * 3 * sizeof(float)) : NULL;
  if (!m.pos || (colours && !m.col)) return;
  for (int i = 0; i < NP; i++) {
    double z = 1 - 2 * (i + 0.5) / NP, r = sqrt(1 - z * z), a = 2.39996 * i;
    m.pos[i * 3] = (float)(r * cos(a)), m.pos[i * 3 + 1] = (float)(r * sin(a)), m.pos[i * 3 + 2] = (float)z;
    if (colours) {
      m.col[i * 3] = (float)(0.5 + 0.5 * cos(a)), m.col[i * 3 + 1] = (float)(0.5 + 0.5 * z);
      m.col[i * 3 + 2] = (float)(i % 7) / 6.0f;
    }
  }
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_mesh_save(ctx, p, &m, fmt));
  spx_mesh_free(&m);
}

static void write_cams(const char *name, int n) {
  spx_camera cams[3];
  for (int k = 0; k < n; k++) {
    double eye[3] = {0.4 * k, 0.2, 3.0 + 0.3 * k}, at[3] = {0, 0, 0}, up[3] = {0, 1, 0};
    CHECK_OK(ctx, spx_camera_look_at(ctx, RW, RH, 30.0, eye, at, up, &cams[k]));
  }
  char p[700];
  path_of(p, sizeof p, name);
  CHECK_OK(ctx, spx_camera_save(ctx, p, cams, n));
}

/* the tool's .npy output for camera k equals the host path on the same chunk */
static int same_as_host(const char *cloud, const char *cams_name, const char *out, int ncams, int batch) {
  char p[700];
  spx_mesh m;
  spx_camera *cams = NULL;
  int nc = 0, ok = 1;
  path_of(p, sizeof p, cloud);
  CHECK_OK(ctx, spx_mesh_load(ctx, p, &m));
  CHECK(m.nf == 0 && m.nv == NP && m.col != NULL);
  path_of(p, sizeof p, cams_name);
  CHECK_OK(ctx, spx_camera_load(ctx, p, &cams, &nc));
  spx_projector *proj = NULL;
  CHECK_OK(ctx, spx_projector_create(ctx, &proj));
  static float in[3 * 4 * RW * RH], ref[3 * 3 * RW * RH];
  for (int c0 = 0; c0 < ncams && proj && nc == ncams; c0 += batch) {
    int n = ncams - c0 < batch ? ncams - c0 : batch;
    spx_project_args a = {1, m.nv, m.pos, m.col, n, cams + c0, SPX_LAYOUT_NCHW};
    CHECK_OK(ctx, spx_project(ctx, proj, &a, in, NULL));
    long drawn = 0;
    for (int q = 0; q < RW * RH; q++) drawn += in[3 * RW * RH + q] != 1.0f;
    CHECK_MSG(drawn > 100, "only %ld points drawn", drawn);
    CHECK_OK(ctx, spx_unet_forward(net, in, n, RH, RW, 0, ref));
    for (int k = 0; k < n; k++) {
      char name[128];
      if (ncams > 1) snprintf(name, sizeof name, "%.*s_%03d.npy", (int)(strlen(out) - 4), out, c0 + k);
      else snprintf(name, sizeof name, "%s", out);
      path_of(p, sizeof p, name);
      spx_array arr;
      memset(&arr, 0, sizeof arr);
      CHECK_OK(ctx, spx_npy_load(ctx, p, &arr));
      int same = arr.ndim == 3 && arr.shape[0] == RH && arr.shape[1] == RW && arr.shape[2] == 3;
      for (int c = 0; c < 3 && same; c++)
        for (int q = 0; q < RW * RH; q++) same &= ((float *)arr.data)[q * 3 + c] == ref[(k * 3 + c) * RW * RH + q];
      if (!same) fprintf(stderr, "  %s differs from the host path\n", name);
      ok &= same;
      spx_array_free(&arr);
    }
  }
  spx_projector_destroy(proj);
  free(cams);
  spx_mesh_free(&m);
  return ok;
}

static void test_point_cloud(void) {
  write_cloud("cloud.ply", SPX_MESH_PLY_BINARY, 1);
  write_cloud("cloud_ascii.ply", SPX_MESH_PLY_ASCII, 1);
  write_cloud("plain.ply", SPX_MESH_PLY_BINARY, 0);
  write_cams("one.json", 1);
  write_cams("three.json", 3);
  CHECK(tool("render --checkpoint net.safetensors --mesh cloud.ply --camera one.json --out c.npy") == 0);
  CHECK(file_has("out.txt", "mesh colors"));
  CHECK(same_as_host("cloud.ply", "one.json", "c.npy", 1, 1));
  CHECK(tool("render --checkpoint net.safetensors --mesh cloud_ascii.ply --camera three.json --out a.npy --batch 2") == 0);
  CHECK(same_as_host("cloud_ascii.ply", "three.json", "a.npy", 3, 2));
  CHECK(tool("render --checkpoint net.safetensors --mesh plain.ply --camera one.json --out g.png") == 0);
  CHECK(file_has("out.txt", "gray (point cloud without colors)") && exists("g.png"));
}

static void test_default_network(void) {
  char p[700];
  make_dir("data");
  make_dir("data/models");
  CHECK(tool_env("SPX_DATA_DIR=./nodata", "render --mesh cloud.ply --camera one.json --out none.npy") == 1);
  CHECK(err_one_line_with("nodata/models/default.safetensors") && err_one_line_with("--checkpoint"));
  CHECK(!exists("none.npy"));
  path_of(p, sizeof p, "data/models/default.safetensors");
  CHECK_OK(ctx, spx_unet_save(net, p, 0));
  CHECK(tool_env("SPX_DATA_DIR=./data", "render --mesh cloud.ply --camera one.json --out d.npy") == 0);
  CHECK(same_as_host("cloud.ply", "one.json", "d.npy", 1, 1));
}

int main(void) {
  snprintf(dir, sizeof dir, "%s", spx_t_tmpdir());
  if (spx_t_open_device(&ctx)) return 1;
  CHECK_OK(ctx, spx_unet_create(ctx, 8, 0, 17, &net));
  char p[700];
  path_of(p, sizeof p, "net.safetensors");
  if (net) CHECK_OK(ctx, spx_unet_save(net, p, 0));
  if (net) {
    SPX_RUN(test_point_cloud);
    SPX_RUN(test_default_network);
  }
  spx_unet_destroy(net);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
