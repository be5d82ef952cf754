/* lib/avatar and spx_fit_closest_points (smplpix/avatar.h, smplpix/fit.h):
 *  - closest points: points near a mesh's surface get a face and barycentric coordinates that
 *    rebuild a surface point as close as brute force over every triangle finds;
 *  - binding: a scan made of the registered body's own vertices (a small model with shape, pose
 *    correctives and a personal template; a similarity, units, body scale) poses exactly as the body
 *    does in another pose; points off the surface come back where they were in the registered pose;
 *  - scan colours: vertex colours interpolated, a texture sampled at the interpolated UVs;
 *  - the avatar: posing through Loop steps, the file written and read back (tensors, colours,
 *    metadata, the network: renders equal bit for bit), render = projection + network, a plain
 *    network file refused as an avatar, and the output policy (a write-protected file, a FIFO). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fit/fit_internal.h"
#include "test.h"

#define SMALL SPX_TEST_DATA "/body/small_model.npz"

static spx_ctx *ctx;
static spx_body_model small;

static void rot_axis(double ax, double ay, double az, double ang, double R[9]) {
  double n = sqrt(ax * ax + ay * ay + az * az), r[3] = {ax / n * ang, ay / n * ang, az / n * ang};
  spx_body_rodrigues(r, R, NULL);
}

/* A registration of the small model: shape, pose, a personal template, a similarity into a scan in
 * centimetres, a body scale. Freed with spx_fit_result_free. */
static void make_registration(spx_fit_result *r, unsigned long long seed) {
  memset(r, 0, sizeof *r);
  const spx_body_model *m = &small;
  r->nv = m->nv, r->nj = m->nj, r->nbetas = m->nbetas, r->nf = m->nf;
  r->betas = malloc(sizeof(double) * (size_t)m->nbetas);
  r->pose = malloc(sizeof(double) * (size_t)m->nj * 3);
  r->template_unposed = malloc(sizeof(double) * (size_t)m->nv * 3);
  for (int i = 0; i < m->nbetas; i++) r->betas[i] = 1.5 * (spx_t_uniform(&seed) - 0.5);
  for (int i = 0; i < m->nj * 3; i++) r->pose[i] = 0.6 * (spx_t_uniform(&seed) - 0.5);
  for (int i = 0; i < m->nv * 3; i++) r->template_unposed[i] = m->v_template[i] + 0.01 * (spx_t_uniform(&seed) - 0.5);
  for (int c = 0; c < 3; c++) r->trans[c] = 0.2 * (spx_t_uniform(&seed) - 0.5), r->sim_t[c] = 0.3 * c - 0.1;
  r->unit_scale = 0.01, r->sim_scale = 0.93, r->body_scale = 1.07;
  rot_axis(0.2, 1, 0.1, 0.7, r->sim_R);
}

/* The registered body (pose, trans) in the model frame (metres, body scale applied). */
static void body_posed(const spx_fit_result *r, const double *pose, const double *trans, double *v) {
  spx_body_params p = {r->nbetas, r->betas, pose, trans, r->template_unposed};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &small, &p, v, NULL));
  for (int i = 0; i < small.nv * 3; i++) v[i] *= r->body_scale;
}

/* model frame (metres) -> scan coordinates (centimetres here) */
static void to_scan(const spx_fit_result *r, const double *x, float *s) {
  for (int a = 0; a < 3; a++)
    s[a] = (float)((r->sim_scale * (r->sim_R[a * 3] * x[0] + r->sim_R[a * 3 + 1] * x[1] + r->sim_R[a * 3 + 2] * x[2]) +
                    r->sim_t[a]) / r->unit_scale);
}

/* A wavy 20 x 20 grid (5 cm cells): points pushed up to 1 mm off its surface. */
static void test_closest_points(void) {
  enum { G = 20, NV = G * G, NF = (G - 1) * (G - 1) * 2, N = 400 };
  static float V[NV * 3], pts[N * 3], bary[N * 3], dist[N];
  static int32_t F[NF * 3], face[N];
  for (int y = 0; y < G; y++)
    for (int x = 0; x < G; x++) {
      float *p = V + (y * G + x) * 3;
      p[0] = 0.05f * x, p[1] = 0.05f * y, p[2] = 0.1f * sinf(0.4f * x) * cosf(0.3f * y);
    }
  int nf = 0;
  for (int y = 0; y + 1 < G; y++)
    for (int x = 0; x + 1 < G; x++) {
      int a = y * G + x;
      int32_t q[6] = {a, a + 1, a + G + 1, a, a + G + 1, a + G};
      memcpy(F + nf * 3, q, sizeof q);
      nf += 2;
    }
  unsigned long long s = 7;
  for (int i = 0; i < N; i++) { /* a surface point, pushed off by up to 1 mm */
    int32_t f = (int32_t)(spx_t_uniform(&s) * NF);
    double u = spx_t_uniform(&s), v = spx_t_uniform(&s);
    if (u + v > 1) u = 1 - u, v = 1 - v;
    for (int d = 0; d < 3; d++)
      pts[i * 3 + d] = (float)((1 - u - v) * V[F[f * 3] * 3 + d] + u * V[F[f * 3 + 1] * 3 + d] + v * V[F[f * 3 + 2] * 3 + d] +
                               0.002 * (spx_t_uniform(&s) - 0.5));
  }
  CHECK_OK(ctx, spx_fit_closest_points(ctx, pts, N, V, NV, F, NF, 1, face, bary, dist));
  int bad = 0;
  for (int i = 0; i < N; i++) {
    double best = INFINITY, q[3] = {0, 0, 0}, sum = 0, e = 0;
    for (int32_t f = 0; f < NF; f++) { /* brute force */
      double p[3], a[3], b[3], c[3], w[3];
      for (int d = 0; d < 3; d++)
        p[d] = pts[i * 3 + d], a[d] = V[F[f * 3] * 3 + d], b[d] = V[F[f * 3 + 1] * 3 + d], c[d] = V[F[f * 3 + 2] * 3 + d];
      best = fmin(best, sqrt(spx_fit_point_tri_closest(p, a, b, c, w)));
    }
    for (int k = 0; k < 3; k++) {
      sum += bary[i * 3 + k];
      bad += bary[i * 3 + k] < -1e-6f;
      for (int d = 0; d < 3; d++) q[d] += bary[i * 3 + k] * V[F[face[i] * 3 + k] * 3 + d];
    }
    for (int d = 0; d < 3; d++) e += (q[d] - pts[i * 3 + d]) * (q[d] - pts[i * 3 + d]);
    bad += fabs(sum - 1) > 1e-5 || fabs(sqrt(e) - dist[i]) > 1e-6 || dist[i] > best + 1e-6 || dist[i] > 0.0018;
  }
  CHECK_MSG(bad == 0, "%d of %d points", bad, N);
}

/* A scan made of the registered body's vertices poses as the body does, correctives included. */
static void test_bind_vertices(void) {
  spx_fit_result r;
  make_registration(&r, 11);
  int nv = small.nv;
  double *v = malloc(sizeof(double) * (size_t)nv * 3), *w = malloc(sizeof(double) * (size_t)nv * 3);
  double *pose2 = malloc(sizeof(double) * (size_t)small.nj * 3), trans2[3] = {0.3, -0.1, 0.2};
  float *scan = malloc(sizeof(float) * (size_t)nv * 3), *out = malloc(sizeof(float) * (size_t)nv * 3);
  unsigned long long s = 5;
  for (int i = 0; i < small.nj * 3; i++) pose2[i] = 0.8 * (spx_t_uniform(&s) - 0.5);
  body_posed(&r, r.pose, r.trans, v);
  for (int i = 0; i < nv; i++) to_scan(&r, v + i * 3, scan + i * 3);
  spx_scan_binding b;
  CHECK_OK(ctx, spx_avatar_bind_scan(ctx, &small, &r, nv, scan, &b));
  CHECK_OK(ctx, spx_avatar_pose_scan(ctx, &small, &r, &b, pose2, trans2, out));
  body_posed(&r, pose2, trans2, w);
  double err = 0;
  for (int i = 0; i < nv * 3; i++) err = fmax(err, fabs(out[i] - w[i]));
  CHECK_MSG(err < 2e-5, "max error %g m", err);
  spx_scan_binding_free(&b);
  spx_fit_result_free(&r);
  free(v), free(w), free(pose2), free(scan), free(out);
}

/* Points off the surface (vertices pushed 3 cm along a direction) come back where they were when
 * posed in the registration's own pose. */
static void test_bind_roundtrip(void) {
  spx_fit_result r;
  make_registration(&r, 23);
  int nv = small.nv;
  double *v = malloc(sizeof(double) * (size_t)nv * 3);
  float *scan = malloc(sizeof(float) * (size_t)nv * 3), *out = malloc(sizeof(float) * (size_t)nv * 3);
  body_posed(&r, r.pose, r.trans, v);
  for (int i = 0; i < nv; i++) {
    v[i * 3] += 0.03 * cos(i), v[i * 3 + 2] += 0.03 * sin(i);
    to_scan(&r, v + i * 3, scan + i * 3);
  }
  spx_scan_binding b;
  CHECK_OK(ctx, spx_avatar_bind_scan(ctx, &small, &r, nv, scan, &b));
  CHECK_OK(ctx, spx_avatar_pose_scan(ctx, &small, &r, &b, r.pose, r.trans, out));
  double err = 0;
  for (int i = 0; i < nv * 3; i++) err = fmax(err, fabs(out[i] - v[i]));
  CHECK_MSG(err < 2e-5, "max error %g m", err);
  spx_scan_binding_free(&b);
  spx_fit_result bad = r;
  bad.nv = nv + 1; /* not of this model */
  CHECK(spx_avatar_bind_scan(ctx, &small, &bad, nv, scan, &b) == SPX_E_ARG && strstr(spx_ctx_message(ctx), "not of this body model"));
  spx_fit_result_free(&r);
  free(v), free(scan), free(out);
}

/* Two triangles with vertex colours, and a 4x4 texture. */
static void test_scan_colors(void) {
  float pos[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, col[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 1, 1, 1};
  float uv[8] = {0, 0, 1, 0, 1, 1, 0, 1}, tex[4 * 4 * 3];
  int32_t faces[6] = {0, 1, 2, 0, 2, 3};
  for (int i = 0; i < 16; i++)
    for (int c = 0; c < 3; c++) tex[i * 3 + c] = (float)(i * 3 + c) / 48.0f;
  spx_mesh m = {4, 2, pos, col, NULL, faces, 4, uv, faces};
  float pts[9] = {1, 0, 0.1f, 0.5f, 0, -0.2f, 0.625f, 0.875f, 0}, got[9];
  CHECK_OK(ctx, spx_avatar_scan_colors(ctx, &m, NULL, 3, pts, got));
  for (int c = 0; c < 3; c++) CHECK_NEAR(got[c], c == 1, 1e-6, 0); /* vertex 1 */
  for (int c = 0; c < 3; c++) CHECK_NEAR(got[3 + c], c < 2 ? 0.5 : 0.0, 1e-6, 0); /* mid edge 0-1 */
  spx_image t = {4, 4, 3, tex};
  CHECK_OK(ctx, spx_avatar_scan_colors(ctx, &m, &t, 3, pts, got));
  /* uv (0.625, 0.875): texel centre (2, 0) (row 0 = the top) */
  for (int c = 0; c < 3; c++) CHECK_NEAR(got[6 + c], tex[(0 * 4 + 2) * 3 + c], 1e-6, 0);
  spx_mesh cloud = {4, 0, pos, col, NULL, NULL, 0, NULL, NULL}, bare = {4, 2, pos, NULL, NULL, faces, 0, NULL, NULL};
  CHECK(spx_avatar_scan_colors(ctx, &cloud, NULL, 3, pts, got) == SPX_E_ARG);
  CHECK(spx_avatar_scan_colors(ctx, &bare, NULL, 3, pts, got) == SPX_E_ARG && strstr(spx_ctx_message(ctx), "no colours"));
  CHECK(spx_avatar_scan_colors(ctx, &bare, &t, 3, pts, got) == SPX_E_ARG);
}

/* An avatar of the small model after one Loop step: posing, the file, rendering. */
static void test_avatar_file(void) {
  spx_fit_result r;
  make_registration(&r, 31);
  spx_avatar *a = NULL, *b = NULL;
  spx_unet *u = NULL;
  CHECK_OK(ctx, spx_avatar_create(ctx, SMALL, &r, 1, &a));
  CHECK_OK(ctx, spx_unet_create(ctx, 8, 0, 3, &u));
  if (!a || !u) return;
  spx_avatar_info ia, ib;
  spx_avatar_get_info(a, &ia);
  CHECK(ia.vertices > small.nv && ia.subdivide == 1 && ia.joints == small.nj);
  size_t n3 = (size_t)ia.vertices * 3;
  float *col = malloc(n3 * sizeof(float)), *va = malloc(n3 * sizeof(float)), *vb = malloc(n3 * sizeof(float));
  double *v = malloc(sizeof(double) * (size_t)small.nv * 3);
  for (size_t i = 0; i < n3; i++) col[i] = (float)((i * 37) % 101) / 100.0f;
  spx_avatar_set_colors(a, col);
  spx_avatar_set_unet(a, u);
  /* posing: the body's vertices come first, unchanged by the Loop step */
  CHECK_OK(ctx, spx_avatar_pose(a, NULL, NULL, va));
  body_posed(&r, r.pose, r.trans, v);
  double err = 0;
  for (int i = 0; i < small.nv * 3; i++) err = fmax(err, fabs(va[i] - v[i]));
  CHECK_MSG(err < 1e-5, "max error %g", err);
  char path[700], net[700];
  spx_t_path(path, sizeof path, "small_avatar.safetensors");
  spx_t_path(net, sizeof net, "small_net.safetensors");
  const char *k[1] = {"note"}, *val[1] = {"test"};
  CHECK_OK(ctx, spx_avatar_save(a, path, 12.5, 48, 64, k, val, 1));
  CHECK_OK(ctx, spx_avatar_load(ctx, path, NULL, &b));
  if (!b) return;
  spx_avatar_get_info(b, &ib);
  CHECK(ib.vertices == ia.vertices && ib.subdivide == 1 && ib.image_width == 48 && ib.image_height == 64 &&
        ib.net_width == 8 && ib.train_cpu_seconds == 12.5 && !strcmp(ib.model_path, SMALL));
  CHECK(!memcmp(spx_avatar_colors(b), col, n3 * sizeof(float)));
  double pose2[15], trans2[3] = {0.1, 0.2, -0.1};
  for (int i = 0; i < 15; i++) pose2[i] = 0.1 * sin(i);
  CHECK_OK(ctx, spx_avatar_pose(a, pose2, trans2, va));
  CHECK_OK(ctx, spx_avatar_pose(b, pose2, trans2, vb));
  CHECK(!memcmp(va, vb, n3 * sizeof(float)));
  /* render = projection + network, the same for the avatar saved and read back */
  spx_camera cam;
  double eye[3] = {0.3, 0.2, 3}, at[3] = {0, 0, 0}, up[3] = {0, 1, 0};
  CHECK_OK(ctx, spx_camera_look_at(ctx, 32, 40, 40, eye, at, up, &cam));
  size_t hw = 32 * 40;
  float *ra = malloc(hw * 3 * sizeof(float)), *rb = malloc(hw * 3 * sizeof(float)), *in = malloc(hw * 4 * sizeof(float));
  float *nchw = malloc(hw * 4 * sizeof(float)), *out = malloc(hw * 3 * sizeof(float));
  CHECK_OK(ctx, spx_avatar_render(a, pose2, trans2, &cam, ra, in));
  CHECK_OK(ctx, spx_avatar_render(b, pose2, trans2, &cam, rb, NULL));
  CHECK(!memcmp(ra, rb, hw * 3 * sizeof(float)));
  spx_projector *pj = NULL;
  CHECK_OK(ctx, spx_projector_create(ctx, &pj));
  spx_project_args pa = {1, ia.vertices, va, col, 1, &cam, SPX_LAYOUT_NCHW};
  CHECK_OK(ctx, spx_project(ctx, pj, &pa, nchw, NULL));
  CHECK_OK(ctx, spx_unet_forward(u, nchw, 1, 40, 32, 0, out));
  int same = 1, covered = 0;
  for (size_t q = 0; q < hw; q++) {
    covered += nchw[3 * hw + q] != 1.0f;
    for (int c = 0; c < 3; c++) same &= out[c * hw + q] == ra[q * 3 + c] && nchw[c * hw + q] == in[q * 4 + c];
  }
  CHECK(same && covered > 20);
  spx_projector_destroy(pj);
  /* a plain network file is not an avatar; the avatar file is a network file */
  CHECK_OK(ctx, spx_unet_save(u, net, 0));
  spx_avatar *c = NULL;
  CHECK(spx_avatar_load(ctx, net, NULL, &c) == SPX_E_FORMAT && strstr(spx_ctx_message(ctx), "not an avatar file") && !c);
  spx_unet *u2 = NULL;
  CHECK_OK(ctx, spx_unet_load(ctx, path, &u2));
  spx_unet_destroy(u2);
  /* the library's output policy: a write-protected file and a FIFO are refused, left as they were */
  char ro[700], fifo[700];
  spx_t_path(ro, sizeof ro, "ro_avatar.safetensors");
  spx_t_path(fifo, sizeof fifo, "fifo_avatar.safetensors");
  unlink(ro), unlink(fifo);
  FILE *f = fopen(ro, "w");
  CHECK(f && fputs("precious", f) >= 0 && fclose(f) == 0 && chmod(ro, 0444) == 0 && mkfifo(fifo, 0666) == 0);
  struct stat sb;
  CHECK(spx_avatar_save(a, ro, 1, 48, 64, NULL, NULL, 0) != SPX_OK && strstr(spx_ctx_message(ctx), ro));
  CHECK(stat(ro, &sb) == 0 && sb.st_size == 8 && (sb.st_mode & 0777) == 0444);
  CHECK(spx_avatar_save(a, fifo, 1, 48, 64, NULL, NULL, 0) != SPX_OK && strstr(spx_ctx_message(ctx), fifo));
  CHECK(stat(fifo, &sb) == 0 && S_ISFIFO(sb.st_mode));
  chmod(ro, 0644), unlink(ro), unlink(fifo);
  spx_avatar_destroy(a), spx_avatar_destroy(b);
  spx_fit_result_free(&r);
  free(col), free(va), free(vb), free(v), free(ra), free(rb), free(in), free(nchw), free(out);
}

int main(void) {
  if (spx_t_open_device(&ctx)) return 1;
  if (spx_body_load(ctx, SMALL, &small)) {
    fprintf(stderr, "%s\n", spx_ctx_message(ctx));
    return 1;
  }
  SPX_RUN(test_closest_points);
  SPX_RUN(test_bind_vertices);
  SPX_RUN(test_bind_roundtrip);
  SPX_RUN(test_scan_colors);
  SPX_RUN(test_avatar_file);
  spx_body_free(&small);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
