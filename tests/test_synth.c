/* lib/synth: the scan's LBS equals the body model's; subjects are reproducible from their seed;
 * the scan is the subdivided body plus bounded clothing/hair displacement; a photo's mask holds
 * the body posed with the same parameters; the device and plain-C photos are bit-equal; the
 * texture carries detail that is visible at photo resolution. */
#include "smplpix/smplpix.h"
#include "test.h"

static spx_ctx *ctx;
static spx_rasterizer *R;
static spx_body_model body;
static spx_image parts;

static float *shaped(const double *betas) {
  float *x = malloc((size_t)body.nv * 3 * sizeof(float));
  for (int32_t i = 0; i < body.nv; i++)
    for (int c = 0; c < 3; c++) {
      double v = body.v_template[i * 3 + c];
      for (int32_t b = 0; b < body.nbetas; b++) v += (double)body.shapedirs[((size_t)i * 3 + c) * body.nbetas + b] * betas[b];
      x[i * 3 + c] = (float)v;
    }
  return x;
}

static void test_lbs_matches_body(void) {
  unsigned long long s = 77;
  int32_t nv = body.nv, nj = body.nj;
  double betas[64], *pose = malloc((size_t)nj * 3 * sizeof(double)), trans[3] = {0.1, -0.2, 0.3};
  for (int32_t b = 0; b < body.nbetas; b++) betas[b] = 2 * spx_t_uniform(&s) - 1;
  for (int32_t k = 0; k < nj * 3; k++) pose[k] = 0.6 * spx_t_uniform(&s) - 0.3;
  int64_t *ws = malloc(((size_t)nv + 1) * sizeof(int64_t));
  int32_t *wj = malloc((size_t)nv * nj * sizeof(int32_t));
  float *w = malloc((size_t)nv * nj * sizeof(float)), *out = malloc((size_t)nv * 3 * sizeof(float));
  int64_t q = 0;
  for (int32_t i = 0; i < nv; i++) {
    ws[i] = q;
    for (int32_t k = 0; k < nj; k++)
      if (body.weights[(size_t)i * nj + k] != 0) {
        wj[q] = k;
        w[q++] = body.weights[(size_t)i * nj + k];
      }
  }
  ws[nv] = q;
  float *x = shaped(betas);
  double *ref = malloc((size_t)nv * 3 * sizeof(double));
  spx_body_params p = {body.nbetas, betas, pose, trans, NULL};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &body, &p, ref, NULL));
  CHECK_OK(ctx, spx_synth_lbs(ctx, &body, betas, body.nbetas, pose, trans, nv, x, ws, wj, w, out));
  double worst = 0;
  for (size_t i = 0; i < (size_t)nv * 3; i++) worst = fmax(worst, fabs(out[i] - ref[i]));
  CHECK_MSG(worst < 2e-5, "worst |synth lbs - body forward| = %g m", worst);
  free(pose), free(ws), free(wj), free(w), free(out), free(x), free(ref);
}

static void test_subject(void) {
  spx_synth_subject a, b, c;
  CHECK_OK(ctx, spx_synth_subject_create(ctx, &body, &parts, 5, 256, &a));
  CHECK_OK(ctx, spx_synth_subject_create(ctx, &body, &parts, 5, 256, &b));
  CHECK_OK(ctx, spx_synth_subject_create(ctx, &body, &parts, 6, 256, &c));
  if (spx_t_fail) return;
  CHECK(a.nf == 16 * body.nf && a.nv > 15 * body.nv && a.nj == body.nj && a.nbetas == body.nbetas);
  CHECK(!memcmp(a.rest, b.rest, (size_t)a.nv * 3 * sizeof(float)));
  CHECK(!memcmp(a.tex, b.tex, (size_t)256 * 256 * 3 * sizeof(float)));
  CHECK(!memcmp(a.col, b.col, (size_t)a.nv * 3 * sizeof(float)));
  CHECK(!memcmp(a.betas, b.betas, (size_t)a.nbetas * sizeof(double)));
  CHECK(memcmp(a.tex, c.tex, (size_t)256 * 256 * 3 * sizeof(float)) != 0);
  CHECK(memcmp(a.betas, c.betas, (size_t)a.nbetas * sizeof(double)) != 0);
  int ok = 1;
  for (int32_t i = 0; i < a.nv; i++) {
    double sw = 0;
    for (int64_t k = a.w_start[i]; k < a.w_start[i + 1]; k++) sw += a.w[k];
    ok &= fabs(sw - 1) < 1e-5;
    for (int ch = 0; ch < 3; ch++) ok &= a.col[i * 3 + ch] >= 0 && a.col[i * 3 + ch] <= 1 && isfinite(a.rest[i * 3 + ch]);
  }
  CHECK(ok);
  /* the scan = the subdivided shaped body, displaced by at most a few centimetres (clothes, hair) */
  spx_loop_plan p1, p2;
  CHECK_OK(ctx, spx_loop_plan_create(ctx, body.nv, body.nf, body.faces, &p1));
  CHECK_OK(ctx, spx_loop_plan_create(ctx, p1.nv_out, p1.nf_out, p1.faces_out, &p2));
  CHECK(p2.nv_out == a.nv && !memcmp(p2.faces_out, a.faces, (size_t)a.nf * 3 * sizeof(int32_t)));
  float *x = shaped(a.betas), *t1 = malloc((size_t)p1.nv_out * 3 * sizeof(float)), *t2 = malloc((size_t)a.nv * 3 * sizeof(float));
  spx_loop_plan_apply(&p1, x, 3, t1);
  spx_loop_plan_apply(&p2, t1, 3, t2);
  double dmax = 0;
  int32_t moved = 0;
  for (int32_t i = 0; i < a.nv; i++) {
    double d = 0;
    for (int ch = 0; ch < 3; ch++) d += (a.rest[i * 3 + ch] - t2[i * 3 + ch]) * (a.rest[i * 3 + ch] - t2[i * 3 + ch]);
    d = sqrt(d);
    dmax = fmax(dmax, d);
    moved += d > 0.004;
  }
  CHECK_MSG(dmax < 0.05 && moved > a.nv / 3, "max displacement %g m, %d of %d vertices moved > 4 mm", dmax, moved, a.nv);
  free(x), free(t1), free(t2);
  spx_loop_plan_free(&p1);
  spx_loop_plan_free(&p2);
  spx_synth_subject_free(&a);
  spx_synth_subject_free(&b);
  spx_synth_subject_free(&c);
}

/* Pose correctives: posedirs that add c * (R_1[0][0] - 1) to every body vertex add the same
 * offset to every scan vertex (Loop rows sum to 1) before skinning. */
static void test_posedirs(void) {
  spx_synth_subject s;
  CHECK_OK(ctx, spx_synth_subject_create(ctx, &body, &parts, 13, 256, &s));
  if (spx_t_fail) return;
  int32_t P = 9 * (body.nj - 1);
  spx_body_model pm = body;
  pm.nposedirs = P;
  pm.posedirs = calloc((size_t)body.nv * 3 * P, sizeof(float));
  const double c[3] = {0.01, -0.02, 0.03}, th = 0.4;
  for (int32_t i = 0; i < body.nv; i++)
    for (int d = 0; d < 3; d++) pm.posedirs[((size_t)i * 3 + d) * P] = (float)c[d];
  double *pose = calloc((size_t)body.nj * 3, sizeof(double)), trans[3] = {0.2, 0, -0.1};
  pose[1 * 3 + 2] = th; /* joint 1 about z: R_1[0][0] - 1 = cos(th) - 1 */
  float *got = malloc((size_t)s.nv * 3 * sizeof(float)), *want = malloc((size_t)s.nv * 3 * sizeof(float));
  float *rest = malloc((size_t)s.nv * 3 * sizeof(float));
  for (size_t i = 0; i < (size_t)s.nv * 3; i++) rest[i] = s.rest[i] + (float)(c[i % 3] * (cos(th) - 1));
  CHECK_OK(ctx, spx_synth_pose(ctx, &pm, &s, pose, trans, got));
  CHECK_OK(ctx, spx_synth_lbs(ctx, &body, s.betas, s.nbetas, pose, trans, s.nv, rest, s.w_start, s.w_joint, s.w, want));
  double worst = 0, moved = 0;
  for (size_t i = 0; i < (size_t)s.nv * 3; i++) worst = fmax(worst, fabs(got[i] - want[i]));
  CHECK_OK(ctx, spx_synth_pose(ctx, &body, &s, pose, trans, want)); /* without correctives */
  for (size_t i = 0; i < (size_t)s.nv * 3; i++) moved = fmax(moved, fabs(got[i] - want[i]));
  CHECK_MSG(worst < 1e-6 && moved > 1e-3, "worst %g, correctives moved %g", worst, moved);
  free(pm.posedirs), free(pose), free(got), free(want), free(rest);
  spx_synth_subject_free(&s);
}

static void test_photo_consistency(void) {
  char path[512];
  snprintf(path, sizeof path, "%s/mocap/01_01.bvh", SPX_REPO_DATA);
  spx_bvh bvh;
  spx_bvh_map map;
  spx_synth_subject s;
  CHECK_OK(ctx, spx_bvh_load(ctx, path, &bvh));
  CHECK_OK(ctx, spx_bvh_map_create(ctx, &bvh, &body, NULL, NULL, &map));
  CHECK_OK(ctx, spx_synth_subject_create(ctx, &body, &parts, 9, 256, &s));
  if (spx_t_fail) return;
  int32_t W = 120, H = 90, nj = body.nj;
  double *pose = malloc((size_t)nj * 3 * sizeof(double)), trans[3], joints[64 * 3];
  CHECK_OK(ctx, spx_bvh_map_pose(ctx, &map, &bvh, &body, 150, pose, trans));
  double *verts = malloc((size_t)body.nv * 3 * sizeof(double));
  spx_body_params p = {s.nbetas, s.betas, pose, trans, NULL};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &body, &p, verts, joints));
  spx_camera cam;
  CHECK_OK(ctx, spx_synth_camera(ctx, W, H, 0.7, 0.3, 4.5, 110, joints, &cam));
  spx_synth_light light = {{0.3, 1, 0.8}, 0.4, 0.7};
  float *rgb = malloc((size_t)W * H * 3 * sizeof(float)), *rgb2 = malloc((size_t)W * H * 3 * sizeof(float));
  uint8_t *mask = malloc((size_t)W * H), *mask2 = malloc((size_t)W * H);
  CHECK_OK(ctx, spx_synth_photo(ctx, R, &body, &s, pose, trans, &cam, &light, 1, rgb, mask, NULL));
  CHECK_OK(ctx, spx_synth_photo(ctx, NULL, &body, &s, pose, trans, &cam, &light, 0, rgb2, mask2, NULL));
  CHECK(!memcmp(rgb, rgb2, (size_t)W * H * 3 * sizeof(float)) && !memcmp(mask, mask2, (size_t)W * H));
  /* every body vertex posed with the same parameters lands on the mask (1 pixel of slack) */
  int32_t in = 0, fg = 0;
  for (int32_t i = 0; i < body.nv; i++) {
    double q[3];
    for (int r = 0; r < 3; r++)
      q[r] = cam.R[r][0] * verts[i * 3] + cam.R[r][1] * verts[i * 3 + 1] + cam.R[r][2] * verts[i * 3 + 2] + cam.t[r];
    int x = (int)floor((cam.K[0][0] * q[0] + cam.K[0][2] * q[2]) / q[2]);
    int y = (int)floor((cam.K[1][1] * q[1] + cam.K[1][2] * q[2]) / q[2]);
    int hit = 0;
    for (int dy = -1; dy <= 1; dy++)
      for (int dx = -1; dx <= 1; dx++)
        if (x + dx >= 0 && y + dy >= 0 && x + dx < W && y + dy < H) hit |= mask[(y + dy) * W + x + dx] != 0;
    in += hit;
  }
  for (int32_t i = 0; i < W * H; i++) fg += mask[i] != 0;
  CHECK_MSG(in >= body.nv * 0.995, "%d of %d body vertices on the mask", in, body.nv);
  CHECK_MSG(fg > 200 && fg < W * H / 2, "%d foreground pixels", fg);
  /* background pixels are white */
  int bg_white = 1;
  for (int32_t i = 0; i < W * H; i++)
    if (!mask[i] && rgb[i * 3] < 0.75f) bg_white = 0;
  CHECK(bg_white && rgb[0] == 1.0f);
  free(pose), free(verts), free(rgb), free(rgb2), free(mask), free(mask2);
  spx_synth_subject_free(&s);
  spx_bvh_map_free(&map);
  spx_bvh_free(&bvh);
}

/* Sum of |neighbour differences| over pixels whose 3x3 neighbourhood is all foreground. */
static double hf_energy(const float *rgb, const uint8_t *mask, int W, int H) {
  double e = 0;
  for (int y = 1; y < H - 1; y++)
    for (int x = 1; x < W - 1; x++) {
      int inner = 1;
      for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) inner &= mask[(y + dy) * W + x + dx] != 0;
      if (!inner) continue;
      for (int c = 0; c < 3; c++)
        e += fabs(rgb[(y * W + x) * 3 + c] - rgb[(y * W + x + 1) * 3 + c]) +
             fabs(rgb[(y * W + x) * 3 + c] - rgb[((y + 1) * W + x) * 3 + c]);
    }
  return e;
}

/* The texture's detail is visible at 410x308: the same photo with the texture blurred (box of
 * 2r+1 texels, r = 6 at 1024 ~ 1.5 photo pixels) has clearly less high-frequency energy. */
static void test_detail(void) {
  int W = 410, H = 308, T = 1024, r = 6;
  double sharp = 0, blurred = 0;
  float *rgb = malloc((size_t)W * H * 3 * sizeof(float)), *tmp = malloc((size_t)T * T * 3 * sizeof(float));
  uint8_t *mask = malloc((size_t)W * H);
  for (uint64_t seed = 21; seed < 23; seed++) {
    spx_synth_subject s;
    CHECK_OK(ctx, spx_synth_subject_create(ctx, &body, &parts, seed, T, &s));
    if (spx_t_fail) break;
    double target[3] = {0, 0.05, 0};
    spx_camera cam;
    CHECK_OK(ctx, spx_synth_camera(ctx, W, H, 0.2, 0.1, 3.0, 420, target, &cam));
    spx_synth_light light = {{0.3, 1, 0.8}, 0.45, 0.7};
    CHECK_OK(ctx, spx_synth_photo(ctx, R, &body, &s, NULL, NULL, &cam, &light, 100 + (uint32_t)seed, rgb, mask, NULL));
    sharp += hf_energy(rgb, mask, W, H);
    for (int pass = 0; pass < 2; pass++) { /* separable box blur: rows, then columns */
      float *src = pass ? tmp : s.tex, *dst = pass ? s.tex : tmp;
      for (int y = 0; y < T; y++)
        for (int x = 0; x < T; x++)
          for (int c = 0; c < 3; c++) {
            double acc = 0;
            for (int k = -r; k <= r; k++) {
              int xx = pass ? x : x + k, yy = pass ? y + k : y;
              xx = xx < 0 ? 0 : xx >= T ? T - 1 : xx;
              yy = yy < 0 ? 0 : yy >= T ? T - 1 : yy;
              acc += src[((size_t)yy * T + xx) * 3 + c];
            }
            dst[((size_t)y * T + x) * 3 + c] = (float)(acc / (2 * r + 1));
          }
    }
    CHECK_OK(ctx, spx_synth_photo(ctx, R, &body, &s, NULL, NULL, &cam, &light, 0, rgb, mask, NULL));
    blurred += hf_energy(rgb, mask, W, H);
    spx_synth_subject_free(&s);
  }
  CHECK_MSG(sharp > 1.3 * blurred, "high-frequency energy %g (texture) vs %g (blurred texture)", sharp, blurred);
  fprintf(stderr, "  high-frequency energy: %.1f with the texture, %.1f with it blurred\n", sharp, blurred);
  free(rgb), free(tmp), free(mask);
}

static void test_errors(void) {
  spx_synth_subject s;
  CHECK(spx_synth_subject_create(ctx, &body, &parts, 1, 100, &s) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "texture size") != NULL);
  spx_body_model nouv = body;
  nouv.vt = NULL;
  CHECK(spx_synth_subject_create(ctx, &nouv, &parts, 1, 256, &s) == SPX_E_ARG);
  CHECK(strstr(spx_ctx_message(ctx), "UVs") != NULL);
}

int main(void) {
  char path[512];
  if (spx_t_open_device(&ctx) || spx_t_no_device(ctx, spx_rasterizer_create(ctx, &R))) return 1;
  snprintf(path, sizeof path, "%s/body/default_body.npz", SPX_REPO_DATA);
  if (spx_body_load(ctx, path, &body)) return fprintf(stderr, "%s\n", spx_ctx_message(ctx)), 1;
  snprintf(path, sizeof path, "%s/body/body_parts_segmentation.png", SPX_REPO_DATA);
  if (spx_png_read(ctx, path, &parts)) return fprintf(stderr, "%s\n", spx_ctx_message(ctx)), 1;
  SPX_RUN(test_lbs_matches_body);
  SPX_RUN(test_subject);
  SPX_RUN(test_posedirs);
  SPX_RUN(test_photo_consistency);
  SPX_RUN(test_detail);
  SPX_RUN(test_errors);
  spx_image_free(&parts);
  spx_body_free(&body);
  spx_rasterizer_destroy(R);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
