/* Body model: loading (SMPL dtypes and layouts, clear errors), the plain-C reference and the
 * device forward against numpy goldens (tests/data/body/make_lbs_golden.py), unposing. */
#include <stdint.h>

#include "core/internal.h"
#include "smplpix/body.h"
#include "smplpix/device.h"
#include "smplpix/npz.h"
#include "test.h"

static spx_ctx *ctx;
static int have_dev;

static double *read_f64(const spx_npz *z, const char *key, size_t *n) {
  spx_array a;
  double *out = NULL;
  CHECK_OK(ctx, spx_npz_read(ctx, z, key, &a));
  if (!a.data) return NULL;
  *n = (size_t)spx_array_numel(&a);
  out = malloc(*n * sizeof(double));
  for (size_t i = 0; i < *n; i++) out[i] = a.dtype == SPX_F64 ? ((double *)a.data)[i] : ((float *)a.data)[i];
  spx_array_free(&a);
  return out;
}

/* compare reference and device against a golden file for model m */
static void check_golden(spx_body_model *m, const char *golden, double ref_tol, double dev_tol) {
  spx_npz g;
  CHECK_OK(ctx, spx_npz_open(ctx, golden, &g));
  if (!g.count) return;
  size_t nb = 0, np = 0, nt = 0, nv = 0, nj = 0;
  double *betas = read_f64(&g, "betas", &nb), *pose = read_f64(&g, "pose", &np), *trans = read_f64(&g, "trans", &nt);
  double *gv = read_f64(&g, "verts", &nv), *gj = read_f64(&g, "joints", &nj);
  CHECK(np == (size_t)m->nj * 3 && nv == (size_t)m->nv * 3 && nj == (size_t)m->nj * 3 && nt == 3);
  if (np != (size_t)m->nj * 3 || nv != (size_t)m->nv * 3) goto done;
  double *v = malloc(nv * sizeof(double)), *j = malloc(nj * sizeof(double));
  spx_body_params p = {(int32_t)nb, betas, pose, trans, NULL};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, m, &p, v, j));
  double maxe = 0, scale = 0;
  for (size_t i = 0; i < nv; i++) maxe = fmax(maxe, fabs(v[i] - gv[i])), scale = fmax(scale, fabs(gv[i]));
  for (size_t i = 0; i < nj; i++) maxe = fmax(maxe, fabs(j[i] - gj[i]));
  CHECK_MSG(maxe <= ref_tol * scale, "reference vs golden max err %g (scale %g)", maxe, scale);
  if (have_dev) {
    float *bf = malloc((nb + 1) * sizeof(float)), *pf = malloc(np * sizeof(float)), tf[3];
    float *vf = malloc(2 * nv * sizeof(float)), *jf = malloc(2 * nj * sizeof(float));
    for (size_t i = 0; i < nb; i++) bf[i] = (float)betas[i];
    for (size_t i = 0; i < np; i++) pf[i] = (float)pose[i];
    for (int i = 0; i < 3; i++) tf[i] = (float)trans[i];
    /* batch of 2: body 0 the golden, body 1 at rest (zero shape/pose/trans) */
    float *bf2 = calloc(2 * nb + 1, sizeof(float)), *pf2 = calloc(2 * np, sizeof(float)), tf2[6] = {0};
    memcpy(bf2, bf, nb * sizeof(float)), memcpy(pf2, pf, np * sizeof(float)), memcpy(tf2, tf, sizeof tf);
    CHECK_OK(ctx, spx_body_forward(ctx, m, 2, (int32_t)nb, bf2, pf2, tf2, NULL, vf, jf));
    double de = 0;
    for (size_t i = 0; i < nv; i++) de = fmax(de, fabs(vf[i] - gv[i]));
    for (size_t i = 0; i < nj; i++) de = fmax(de, fabs(jf[i] - gj[i]));
    CHECK_MSG(de <= dev_tol * scale, "device vs golden max err %g (scale %g)", de, scale);
    double re = 0;
    for (size_t i = 0; i < nv; i++) re = fmax(re, fabs(vf[nv + i] - m->v_template[i]));
    CHECK_MSG(re <= 1e-6 * scale, "rest body differs from v_template by %g", re);
    printf("  %s: ref err %.3g, device err %.3g (scale %.3g)\n", golden, maxe, de, scale);
    free(bf), free(pf), free(vf), free(jf), free(bf2), free(pf2);
  }
  free(v), free(j);
done:
  free(betas), free(pose), free(trans), free(gv), free(gj);
  spx_npz_close(&g);
}

static void test_small_golden(void) {
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_TEST_DATA "/body/small_model.npz", &m));
  CHECK(m.nv == 50 && m.nj == 5 && m.nbetas == 4 && m.nposedirs == 36 && m.nf == 50);
  CHECK(m.parents && m.parents[0] == -1 && m.parents[2] == 1 && m.parents[4] == 3);
  if (m.nv == 50) check_golden(&m, SPX_TEST_DATA "/body/small_golden.npz", 1e-12, 2e-6);
  spx_body_free(&m);
}

static void test_default_golden(void) {
  const char *path = SPX_REPO_DATA "/body/default_body.npz";
  if (!spx_t_file_exists(path)) {
    printf("  (no %s yet)\n", path);
    return;
  }
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, path, &m));
  if (m.nv > 0) check_golden(&m, SPX_TEST_DATA "/body/default_golden.npz", 1e-6, 2e-5);
  spx_body_free(&m);
}

/* write the small model back with some keys replaced, to test dtypes/layouts and errors */
static int save_variant(const char *name, const char *key, const spx_array *repl, const char *drop, char *path,
                        size_t cap) {
  spx_npz z;
  if (spx_npz_open(ctx, SPX_TEST_DATA "/body/small_model.npz", &z)) return 0;
  spx_array arr[16];
  const char *keys[16];
  int n = 0;
  for (int32_t i = 0; i < z.count && n < 16; i++) {
    if (drop && !strcmp(z.members[i].key, drop)) continue;
    if (spx_npz_read_index(ctx, &z, i, &arr[n])) break;
    keys[n] = z.members[i].key;
    if (key && !strcmp(keys[n], key)) {
      spx_array_free(&arr[n]);
      arr[n] = *repl;
      arr[n].data = malloc(repl->nbytes);
      memcpy(arr[n].data, repl->data, repl->nbytes);
    }
    n++;
  }
  spx_t_path(path, cap, name);
  spx_status st = spx_npz_save(ctx, path, n, keys, arr, 0);
  for (int i = 0; i < n; i++) spx_array_free(&arr[i]);
  spx_npz_close(&z);
  return st == SPX_OK;
}

static void test_variants(void) {
  char path[512];
  /* uint32 kintree with root 2^32-1 */
  uint32_t kt[10] = {0xFFFFFFFFu, 0, 1, 0, 3, 0, 1, 2, 3, 4};
  spx_array a = {SPX_U32, 2, {2, 5}, kt, sizeof kt};
  CHECK(save_variant("v_u32.npz", "kintree_table", &a, NULL, path, sizeof path));
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, path, &m));
  CHECK(m.nj == 5 && m.parents && m.parents[0] == -1 && m.parents[4] == 3);
  spx_body_free(&m);
  /* int32 kintree with -1, no posedirs */
  int32_t kt2[10] = {-1, 0, 1, 0, 3, 0, 1, 2, 3, 4};
  spx_array b = {SPX_I32, 2, {2, 5}, kt2, sizeof kt2};
  CHECK(save_variant("v_i32.npz", "kintree_table", &b, "posedirs", path, sizeof path));
  CHECK_OK(ctx, spx_body_load(ctx, path, &m));
  CHECK(m.posedirs == NULL && m.nposedirs == 0);
  spx_body_free(&m);
  /* smplx-style flat posedirs (9(K-1) x 3N) give the same model */
  {
    spx_body_model ref;
    CHECK_OK(ctx, spx_body_load(ctx, SPX_TEST_DATA "/body/small_model.npz", &ref));
    if (ref.posedirs) {
      float flat[36 * 150];
      for (int p = 0; p < 36; p++)
        for (int r = 0; r < 150; r++) flat[p * 150 + r] = ref.posedirs[r * 36 + p];
      spx_array fp = {SPX_F32, 2, {36, 150}, flat, sizeof flat};
      CHECK(save_variant("v_flat.npz", "posedirs", &fp, NULL, path, sizeof path));
      CHECK_OK(ctx, spx_body_load(ctx, path, &m));
      CHECK(m.posedirs && memcmp(m.posedirs, ref.posedirs, sizeof flat) == 0);
      spx_body_free(&m);
    }
    spx_body_free(&ref);
  }
  /* a parent after its child is rejected with the key named */
  int32_t kt3[10] = {-1, 2, 1, 0, 3, 0, 1, 2, 3, 4};
  spx_array c = {SPX_I32, 2, {2, 5}, kt3, sizeof kt3};
  CHECK(save_variant("v_bad_tree.npz", "kintree_table", &c, NULL, path, sizeof path));
  CHECK(spx_body_load(ctx, path, &m) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "kintree_table") != NULL);
  /* weights of the wrong shape: message names key and expected shape */
  float w[50 * 4] = {0};
  spx_array d = {SPX_F32, 2, {50, 4}, w, sizeof w};
  CHECK(save_variant("v_bad_w.npz", "weights", &d, NULL, path, sizeof path));
  CHECK(spx_body_load(ctx, path, &m) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "'weights'") && strstr(spx_ctx_message(ctx), "(50, 5)"));
  /* missing J_regressor */
  CHECK(save_variant("v_no_j.npz", NULL, NULL, "J_regressor", path, sizeof path));
  CHECK(spx_body_load(ctx, path, &m) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "J_regressor") != NULL);
  /* face index out of range */
  int64_t f[150];
  for (int i = 0; i < 150; i++) f[i] = i % 50;
  f[77] = 50;
  spx_array e = {SPX_I64, 2, {50, 3}, f, sizeof f};
  CHECK(save_variant("v_bad_f.npz", "f", &e, NULL, path, sizeof path));
  CHECK(spx_body_load(ctx, path, &m) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "'f'") != NULL);
  /* NaN in v_template */
  spx_body_model ok;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_TEST_DATA "/body/small_model.npz", &ok));
  if (ok.nv == 50) {
    float vt[150];
    memcpy(vt, ok.v_template, sizeof vt);
    vt[4] = NAN;
    spx_array g = {SPX_F32, 2, {50, 3}, vt, sizeof vt};
    CHECK(save_variant("v_nan.npz", "v_template", &g, NULL, path, sizeof path));
    CHECK(spx_body_load(ctx, path, &m) == SPX_E_NUMERIC);
  }
  spx_body_free(&ok);
}

static void test_unpose(void) {
  spx_body_model m;
  CHECK_OK(ctx, spx_body_load(ctx, SPX_TEST_DATA "/body/small_model.npz", &m));
  if (m.nv != 50) return;
  double betas[4], pose[15], trans[3], base[150], posed[150], back[150], again[150];
  unsigned long long rng = spx_t_small_params(99, 0.8, betas, pose, trans);
  /* a personal template: model template + per-vertex displacements */
  for (int i = 0; i < 150; i++) base[i] = m.v_template[i] + 0.05 * (spx_t_uniform(&rng) - 0.5);
  spx_body_params p = {4, betas, pose, trans, base};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &m, &p, posed, NULL));
  spx_body_params q = p;
  q.v_base = NULL;
  CHECK_OK(ctx, spx_body_unpose_ref(ctx, &m, &q, posed, 1, back));
  double e = 0, moved = 0;
  for (int i = 0; i < 150; i++) e = fmax(e, fabs(back[i] - base[i])), moved = fmax(moved, fabs(posed[i] - base[i]));
  CHECK_MSG(e < 1e-10, "unpose(pose(T)) - T = %g", e);
  CHECK(moved > 0.1); /* the pose really moved the body */
  /* reposing / reshaping T*: the personal template under the same pose and shape gives the
   * scan back; under another shape it differs from the scan by exactly that shape's blend when
   * the pose is the rest pose */
  spx_body_params r = {4, betas, pose, trans, back};
  CHECK_OK(ctx, spx_body_forward_ref(ctx, &m, &r, again, NULL));
  e = 0;
  for (int i = 0; i < 150; i++) e = fmax(e, fabs(again[i] - posed[i]));
  CHECK_MSG(e < 1e-10, "repose(unpose(scan)) - scan = %g", e);
  /* without remove_shape the result is the shaped template: T* + shapedirs . betas */
  double shaped[150];
  CHECK_OK(ctx, spx_body_unpose_ref(ctx, &m, &q, posed, 0, shaped));
  e = 0;
  for (int i = 0; i < 150; i++) {
    double sb = 0;
    for (int s = 0; s < 4; s++) sb += m.shapedirs[i * 4 + s] * betas[s];
    e = fmax(e, fabs(shaped[i] - (base[i] + sb)));
  }
  CHECK_MSG(e < 1e-10, "unpose without shape removal: %g", e);
  spx_body_free(&m);
}

int main(void) {
  CHECK(spx_ctx_create(&ctx) == SPX_OK);
  have_dev = spx_device_open(ctx, NULL) == SPX_OK;
  if (!have_dev) printf("  no OpenCL device: %s (device checks skipped)\n", spx_ctx_message(ctx));
  SPX_RUN(test_small_golden);
  SPX_RUN(test_variants);
  SPX_RUN(test_unpose);
  SPX_RUN(test_default_golden);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
