/* NumPy .npy: files written by NumPy (tests/data/npy, made by make_npy.py) load with the right
 * dtype, shape and values; our writer produces the same bytes as np.save; malformed headers,
 * short/long data, lying shapes are rejected with messages naming the file. */
#include "io_common.h"
#include "smplpix/npy.h"

static spx_ctx *ctx;

static void ref_path(char *out, size_t cap, const char *name) { snprintf(out, cap, "%s/npy/%s", SPX_TEST_DATA, name); }

static int load_ref(const char *name, spx_array *a) {
  char p[512];
  ref_path(p, sizeof p, name);
  spx_status st = spx_npy_load(ctx, p, a);
  CHECK_MSG(st == SPX_OK, "%s: %s", name, spx_ctx_message(ctx));
  return st == SPX_OK;
}

static void test_reference_values(void) {
  spx_array a;
  if (load_ref("f4_2x3.npy", &a)) {
    CHECK(a.dtype == SPX_F32 && a.ndim == 2 && a.shape[0] == 2 && a.shape[1] == 3 && a.nbytes == 24);
    const float *f = a.data;
    for (int i = 0; i < 6; i++) CHECK(f[i] == i * 0.5f - 1.0f);
    spx_array_free(&a);
  }
  if (load_ref("f8_3.npy", &a)) {
    const double *d = a.data;
    CHECK(a.dtype == SPX_F64 && a.ndim == 1 && a.shape[0] == 3);
    CHECK(d[0] == 1e300 && d[1] == -0.1 && d[2] == 4.9406564584124654e-324);
    spx_array_free(&a);
  }
  if (load_ref("u1_3.npy", &a)) {
    const uint8_t *u = a.data;
    CHECK(a.dtype == SPX_U8 && a.shape[0] == 3 && u[0] == 0 && u[1] == 1 && u[2] == 255);
    spx_array_free(&a);
  }
  if (load_ref("i4_3.npy", &a)) {
    const int32_t *v = a.data;
    CHECK(a.dtype == SPX_I32 && v[0] == INT32_MIN && v[1] == 0 && v[2] == INT32_MAX);
    spx_array_free(&a);
  }
  if (load_ref("i8_3.npy", &a)) {
    const int64_t *v = a.data;
    CHECK(a.dtype == SPX_I64 && v[0] == -(INT64_C(1) << 62) && v[1] == 5 && v[2] == (INT64_C(1) << 53) + 1);
    spx_array_free(&a);
  }
  if (load_ref("be_f4_3.npy", &a)) { /* big endian, swapped on load */
    const float *f = a.data;
    CHECK(a.dtype == SPX_F32 && f[0] == 1.5f && f[1] == -2.25f && f[2] == 3e-5f);
    spx_array_free(&a);
  }
  if (load_ref("be_i8_2.npy", &a)) {
    const int64_t *v = a.data;
    CHECK(a.dtype == SPX_I64 && v[0] == -3 && v[1] == (INT64_C(1) << 40));
    spx_array_free(&a);
  }
  if (load_ref("f4_0d.npy", &a)) {
    CHECK(a.ndim == 0 && spx_array_numel(&a) == 1 && a.nbytes == 4 && *(const float *)a.data == 3.25f);
    spx_array_free(&a);
  }
  if (load_ref("f4_2x3x4.npy", &a)) {
    CHECK(a.ndim == 3 && a.shape[0] == 2 && a.shape[1] == 3 && a.shape[2] == 4 && spx_array_numel(&a) == 24);
    const float *f = a.data;
    int ok = 1;
    for (int i = 0; i < 24; i++) ok &= f[i] == (float)i;
    CHECK(ok);
    spx_array_free(&a);
  }
  if (load_ref("f4_0x3.npy", &a)) {
    CHECK(a.ndim == 2 && a.shape[0] == 0 && a.shape[1] == 3 && a.nbytes == 0 && spx_array_numel(&a) == 0);
    spx_array_free(&a);
  }
  if (load_ref("f4_v2.npy", &a)) { /* format 2.0 header */
    CHECK(a.ndim == 1 && ((const float *)a.data)[1] == 8.0f);
    spx_array_free(&a);
  }
  float *f = NULL;
  if (load_ref("f2_3.npy", &a)) {
    CHECK(a.dtype == SPX_F16);
    CHECK_OK(ctx, spx_array_to_f32(ctx, &a, &f));
    if (f) CHECK(f[0] == 1.0f && f[1] == -0.5f && f[2] == 65504.0f);
    free(f);
    spx_array_free(&a);
  }
  if (load_ref("b1_3.npy", &a)) {
    CHECK(a.dtype == SPX_BOOL);
    CHECK_OK(ctx, spx_array_to_f32(ctx, &a, &f));
    if (f) CHECK(f[0] == 1.0f && f[1] == 0.0f && f[2] == 1.0f);
    free(f);
    spx_array_free(&a);
  }
  if (load_ref("i8_3.npy", &a)) {
    CHECK_OK(ctx, spx_array_to_f32(ctx, &a, &f));
    if (f) CHECK(f[0] == -4611686018427387904.0f && f[1] == 5.0f);
    free(f);
    spx_array_free(&a);
  }
  if (load_ref("f8_3.npy", &a)) {
    CHECK_OK(ctx, spx_array_to_f32(ctx, &a, &f));
    if (f) CHECK(isinf(f[0]) && f[1] == -0.1f && f[2] == 0.0f);
    free(f);
    spx_array_free(&a);
  }
}

/* Our writer must produce NumPy's bytes exactly (np.save in make_npy.py). */
static void test_writer_matches_numpy(void) {
  const char *names[] = {"f4_2x3.npy", "f8_3.npy",   "u1_3.npy", "i4_3.npy", "i8_3.npy", "f4_0d.npy",
                         "f4_2x3x4.npy", "f4_0x3.npy", "f2_3.npy", "b1_3.npy"};
  for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
    spx_array a;
    if (!load_ref(names[i], &a)) continue;
    char out[512], ref[512];
    spx_t_path(out, sizeof out, names[i]);
    ref_path(ref, sizeof ref, names[i]);
    CHECK_OK(ctx, spx_npy_save(ctx, out, &a));
    unsigned char *rb;
    size_t rn;
    if (spx_read_file(ctx, ref, 1 << 20, &rb, &rn) == SPX_OK) {
      CHECK_MSG(t_file_equals(out, rb, rn), "%s: bytes differ from np.save", names[i]);
      free(rb);
    }
    spx_array_free(&a);
  }
  /* spx_npy_save_f32 with a shape */
  float d[6] = {-1, -0.5f, 0, 0.5f, 1, 1.5f};
  int64_t shape[2] = {2, 3};
  char out[512], ref[512];
  spx_t_path(out, sizeof out, "save_f32.npy");
  ref_path(ref, sizeof ref, "f4_2x3.npy");
  CHECK_OK(ctx, spx_npy_save_f32(ctx, out, d, 2, shape));
  unsigned char *rb;
  size_t rn;
  if (spx_read_file(ctx, ref, 1 << 20, &rb, &rn) == SPX_OK) {
    CHECK(t_file_equals(out, rb, rn));
    free(rb);
  }
}

/* Build an in-memory .npy: header dict text + data bytes. */
static size_t make_npy(unsigned char *buf, const char *dict, size_t ndata, int version) {
  size_t pre = version == 1 ? 10 : 12, hl = strlen(dict);
  memcpy(buf, "\x93NUMPY", 6);
  buf[6] = (unsigned char)version;
  buf[7] = 0;
  if (version == 1) {
    buf[8] = (unsigned char)hl;
    buf[9] = (unsigned char)(hl >> 8);
  } else {
    for (int i = 0; i < 4; i++) buf[8 + i] = (unsigned char)(hl >> (8 * i));
  }
  memcpy(buf + pre, dict, hl);
  memset(buf + pre + hl, 0x3f, ndata);
  return pre + hl + ndata;
}

static void test_bad_inputs(void) {
  static unsigned char buf[1 << 12];
  spx_array a;
  size_t n;
  /* good baseline */
  n = make_npy(buf, "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }\n", 24, 1);
  CHECK_OK(ctx, spx_npy_parse(ctx, "ok.npy", buf, n, &a));
  spx_array_free(&a);
  /* any key order, double quotes, no trailing comma */
  n = make_npy(buf, "{\"shape\": (3,), \"descr\": \"<i4\", \"fortran_order\": False}  \n", 12, 1);
  CHECK_OK(ctx, spx_npy_parse(ctx, "order.npy", buf, n, &a));
  CHECK(a.dtype == SPX_I32 && a.shape[0] == 3);
  spx_array_free(&a);

  /* one header, data bytes, file name, status, message word; zeroed: the output is left all zero */
  static const struct {
    const char *dict;
    size_t ndata;
    const char *name;
    spx_status want;
    const char *needle;
    int zeroed;
  } bad[] = {
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }\n", 23, "short.npy", SPX_E_FORMAT, "truncated", 1},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }\n", 25, "long.npy", SPX_E_FORMAT, "trailing", 1},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (4611686018427387904, 4611686018427387904), }\n", 0,
       "huge.npy", SPX_E_FORMAT, "overflow", 0},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999, ), }\n", 0, "digits.npy",
       SPX_E_FORMAT, "shape", 0},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (-1,), }\n", 0, "neg.npy", SPX_E_FORMAT, "shape", 0},
      {"{'descr': '<c8', 'fortran_order': False, 'shape': (1,), }\n", 8, "complex.npy", SPX_E_UNSUPPORTED, "<c8", 0},
      {"{'descr': '|O', 'fortran_order': False, 'shape': (1,), }\n", 8, "obj.npy", SPX_E_UNSUPPORTED, "dtype", 0},
      {"{'descr': [('a', '<f4')], 'fortran_order': False, 'shape': (1,), }\n", 4, "rec.npy", SPX_E_UNSUPPORTED,
       "structured", 0},
      {"{'descr': '<f4', 'fortran_order': True, 'shape': (2, 2), }\n", 16, "fort.npy", SPX_E_UNSUPPORTED, "Fortran", 0},
      {"{'descr': '<f4', 'fortran_order': False, }\n", 0, "noshape.npy", SPX_E_FORMAT, "shape", 0},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1,1,1,1,1,1,1,1,1), }\n", 4, "dims.npy", SPX_E_UNSUPPORTED,
       "dimensions", 0},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1,), 'x': 1}\n", 4, "key.npy", SPX_E_FORMAT, "'x'", 0},
      {"{'descr': '<f4', 'fortran_order': False, 'shape': (1,), }", 4, "nonl.npy", SPX_E_FORMAT, "newline", 0},
  };
  for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
    n = make_npy(buf, bad[k].dict, bad[k].ndata, 1);
    CHECK_ERR(ctx, spx_npy_parse(ctx, bad[k].name, buf, n, &a), bad[k].want, bad[k].name, bad[k].needle);
    if (bad[k].zeroed) CHECK(t_is_zero(&a, sizeof a));
  }
  /* header length beyond the file, and over 64 KiB (format 2.0) */
  n = make_npy(buf, "{'descr': '<f4', 'fortran_order': False, 'shape': (1,), }\n", 4, 1);
  buf[9] = 0x7f;
  CHECK_ERR(ctx, spx_npy_parse(ctx, "cut.npy", buf, n, &a), SPX_E_FORMAT, "cut.npy", "truncated");
  n = make_npy(buf, "{'descr': '<f4', 'fortran_order': False, 'shape': (1,), }\n", 4, 2);
  buf[10] = 0x01; /* header length 65536 + ... */
  CHECK_ERR(ctx, spx_npy_parse(ctx, "big.npy", buf, n, &a), SPX_E_FORMAT, "big.npy", "64 KiB");
  CHECK_ERR(ctx, spx_npy_parse(ctx, "magic.npy", "\x93NUMPX\x01\x00\x00\x00", 10, &a), SPX_E_FORMAT, "magic.npy", "magic");
  n = make_npy(buf, "{'descr': '<f4', 'fortran_order': False, 'shape': (1,), }\n", 4, 1);
  buf[6] = 9;
  CHECK_ERR(ctx, spx_npy_parse(ctx, "ver.npy", buf, n, &a), SPX_E_UNSUPPORTED, "ver.npy", "version");
  CHECK(t_is_zero(&a, sizeof a));
  /* every truncation of a real file fails cleanly */
  n = make_npy(buf, "{'descr': '<f8', 'fortran_order': False, 'shape': (2,), }\n", 16, 1);
  int all_fail = 1;
  for (size_t k = 0; k < n; k++)
    if (spx_npy_parse(ctx, "prefix.npy", buf, k, &a) == SPX_OK) all_fail = 0;
  CHECK(all_fail);
  /* a missing file names the path */
  CHECK_ERR(ctx, spx_npy_load(ctx, "/nonexistent/x.npy", &a), SPX_E_IO, "/nonexistent/x.npy", NULL);
  /* load() applies the same size rule as parse() */
  char p[512];
  spx_t_path(p, sizeof p, "short_file.npy");
  n = make_npy(buf, "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }\n", 20, 1);
  CHECK(t_write_file(p, buf, n));
  CHECK_ERR(ctx, spx_npy_load(ctx, p, &a), SPX_E_FORMAT, "short_file.npy", "truncated");
}

static void test_failed_save(void) {
  float d[2] = {1, 2};
  int64_t shape[1] = {2};
  CHECK_ERR(ctx, spx_npy_save_f32(ctx, "/nonexistent-dir/a.npy", d, 1, shape), SPX_E_IO, "/nonexistent-dir/a.npy", NULL);
  CHECK(!spx_t_file_exists("/nonexistent-dir/a.npy"));
  /* an existing file is untouched when the save is refused */
  char p[512];
  spx_t_path(p, sizeof p, "keep.npy");
  CHECK(t_write_file(p, "previous", 8));
  spx_array bad = {0};
  bad.dtype = SPX_F32;
  bad.ndim = 1;
  bad.shape[0] = 3;
  bad.nbytes = 8; /* disagrees with the shape */
  bad.data = d;
  CHECK_ERR(ctx, spx_npy_save(ctx, p, &bad), SPX_E_ARG, "keep.npy", NULL);
  CHECK(t_file_equals(p, "previous", 8));
  /* a successful save replaces it */
  CHECK_OK(ctx, spx_npy_save_f32(ctx, p, d, 1, shape));
  spx_array a;
  CHECK_OK(ctx, spx_npy_load(ctx, p, &a));
  CHECK(a.nbytes == 8 && ((float *)a.data)[1] == 2.0f);
  spx_array_free(&a);
}

int main(void) {
  if (spx_ctx_create(&ctx) != SPX_OK) return 1;
  SPX_RUN(test_reference_values);
  SPX_RUN(test_writer_matches_numpy);
  SPX_RUN(test_bad_inputs);
  SPX_RUN(test_failed_save);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
