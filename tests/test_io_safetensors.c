/* safetensors: round trips of every dtype with metadata, the reference file written by the
 * official Python package (tests/data/safetensors/make_st.py), a file for the Python-side check,
 * and hostile headers that must fail with a clear error and never crash. */
#include <stdint.h>
#include <string.h>

#include "smplpix/smplpix.h"
#include "test.h"

static spx_ctx *ctx;

static void test_roundtrip(void) {
  double f64[3] = {1.0 / 3.0, -1e300, 4.9e-324};
  float f32[2][3] = {{1.5f, -2.0f, 1e-45f}, {3.0f, 4.0f, -0.0f}};
  uint16_t f16[2] = {0x3c00, 0xfbff};
  int64_t i64[2] = {INT64_MIN, INT64_MAX};
  int32_t i32[1] = {-7};
  int8_t i8[3] = {-128, 0, 127};
  uint8_t u8[2] = {0, 255};
  uint8_t bl[3] = {1, 0, 1};
  uint32_t u32[1] = {0xfffffffeu};
  uint64_t u64[1] = {UINT64_MAX};
  float scalar = 2.5f;
  float one8 = 9.0f;
  spx_st_entry e[] = {
      {"f64", SPX_F64, 1, {3}, f64},         {"layer.f32", SPX_F32, 2, {2, 3}, f32},
      {"f16", SPX_F16, 1, {2}, f16},         {"i64", SPX_I64, 2, {1, 2}, i64},
      {"i32", SPX_I32, 1, {1}, i32},         {"i8", SPX_I8, 1, {3}, i8},
      {"u8", SPX_U8, 1, {2}, u8},            {"bool", SPX_BOOL, 1, {3}, bl},
      {"u32", SPX_U32, 1, {1}, u32},         {"u64", SPX_U64, 1, {1}, u64},
      {"scalar", SPX_F32, 0, {0}, &scalar},  {"empty", SPX_F32, 2, {4, 0}, NULL},
      {"eight", SPX_F32, 8, {1, 1, 1, 1, 1, 1, 1, 1}, &one8},
      {"name with \"quotes\" and \\ and \xc3\xa9", SPX_U8, 1, {1}, u8},
  };
  int n = (int)(sizeof e / sizeof e[0]);
  const char *mk[] = {"format", "empty", "json\"chars"};
  const char *mv[] = {"pt", "", "a\nb\\c"};
  char path[512];
  spx_t_path(path, sizeof path, "rt.safetensors");
  CHECK_OK(ctx, spx_st_save(ctx, path, e, n, mk, mv, 3));
  spx_st_file f;
  CHECK_OK(ctx, spx_st_load(ctx, path, &f));
  CHECK(f.count == n && f.nmeta == 3);
  /* header length is a multiple of 8 and the data section is 8-byte aligned in the file */
  uint64_t hlen = 0;
  for (int i = 7; f.blob && i >= 0; i--) hlen = hlen << 8 | f.blob[i];
  CHECK(hlen % 8 == 0 && f.blob[8] == '{');
  for (int i = 0; i < n; i++) {
    const spx_st_tensor *t = spx_st_find(&f, e[i].name);
    CHECK_MSG(t != NULL, "missing %s", e[i].name);
    if (!t) continue;
    CHECK(t == &f.tensors[i]); /* header order kept */
    CHECK(t->dtype == e[i].dtype && t->ndim == e[i].ndim);
    size_t numel = 1;
    for (int d = 0; d < e[i].ndim; d++) {
      CHECK(t->shape[d] == e[i].shape[d]);
      numel *= (size_t)e[i].shape[d];
    }
    CHECK(t->nbytes == numel * spx_dtype_size(e[i].dtype));
    CHECK_MSG(t->nbytes == 0 || memcmp(t->data, e[i].data, t->nbytes) == 0, "data of %s", e[i].name);
  }
  for (int i = 0; i < 3; i++) CHECK(spx_st_meta(&f, mk[i]) && strcmp(spx_st_meta(&f, mk[i]), mv[i]) == 0);
  CHECK(spx_st_meta(&f, "nope") == NULL && spx_st_find(&f, "nope") == NULL);
  spx_st_free(&f);
  /* no tensors, no metadata */
  spx_t_path(path, sizeof path, "nothing.safetensors");
  CHECK_OK(ctx, spx_st_save(ctx, path, NULL, 0, NULL, NULL, 0));
  CHECK_OK(ctx, spx_st_load(ctx, path, &f));
  CHECK(f.count == 0 && f.nmeta == 0 && f.blob_size == 16);
  spx_st_free(&f);
}

static void test_reference_file(void) {
  spx_st_file f;
  CHECK_OK(ctx, spx_st_load(ctx, SPX_TEST_DATA "/safetensors/ref.safetensors", &f));
  CHECK(f.count == 13);
  CHECK(spx_st_meta(&f, "format") && strcmp(spx_st_meta(&f, "format"), "pt") == 0);
  CHECK(spx_st_meta(&f, "note") && strcmp(spx_st_meta(&f, "note"), "smplpix test") == 0);
  const spx_st_tensor *t = spx_st_find(&f, "f32");
  CHECK(t && t->dtype == SPX_F32 && t->ndim == 2 && t->shape[0] == 2 && t->shape[1] == 3);
  if (t) {
    float v[6];
    memcpy(v, t->data, sizeof v);
    for (int i = 0; i < 6; i++) CHECK(v[i] == (float)i * 0.5f - 1.0f);
  }
  t = spx_st_find(&f, "f16");
  uint16_t h[4], hw[4] = {0x3c00, 0x3800, 0xc000, 0x7bff};
  CHECK(t && t->dtype == SPX_F16 && t->nbytes == 8);
  if (t) CHECK(memcmp(t->data, hw, 8) == 0 && memcpy(h, t->data, 8));
  t = spx_st_find(&f, "i64");
  int64_t i64[2];
  CHECK(t && t->dtype == SPX_I64);
  if (t) {
    memcpy(i64, t->data, 16);
    CHECK(i64[0] == -(INT64_C(1) << 40) && i64[1] == 7);
  }
  t = spx_st_find(&f, "u64");
  uint64_t u64;
  CHECK(t && t->dtype == SPX_U64);
  if (t) {
    memcpy(&u64, t->data, 8);
    CHECK(u64 == (UINT64_C(1) << 63) + 5);
  }
  t = spx_st_find(&f, "bool");
  CHECK(t && t->dtype == SPX_BOOL && t->nbytes == 3 && memcmp(t->data, "\1\0\1", 3) == 0);
  t = spx_st_find(&f, "u32");
  uint32_t u32;
  CHECK(t && t->dtype == SPX_U32);
  if (t) {
    memcpy(&u32, t->data, 4);
    CHECK(u32 == 4000000000u);
  }
  t = spx_st_find(&f, "i8");
  CHECK(t && t->dtype == SPX_I8 && ((const int8_t *)t->data)[0] == -128);
  t = spx_st_find(&f, "u8");
  CHECK(t && t->dtype == SPX_U8 && ((const uint8_t *)t->data)[1] == 255);
  t = spx_st_find(&f, "i32");
  CHECK(t && t->dtype == SPX_I32 && t->ndim == 2 && t->shape[1] == 1);
  t = spx_st_find(&f, "f64");
  double d[2];
  CHECK(t && t->dtype == SPX_F64);
  if (t) {
    memcpy(d, t->data, 16);
    CHECK(d[0] == 1.5 && d[1] == -2.25);
  }
  t = spx_st_find(&f, "scalar");
  CHECK(t && t->ndim == 0 && t->nbytes == 4);
  t = spx_st_find(&f, "empty");
  CHECK(t && t->ndim == 2 && t->shape[0] == 0 && t->shape[1] == 3 && t->nbytes == 0);
  t = spx_st_find(&f, "down1.maxpool_conv.1.double_conv.0.weight");
  CHECK(t && t->ndim == 4 && t->shape[0] == 2 && t->shape[3] == 3 && t->nbytes == 72);
  spx_st_free(&f);
}

/* The file that `make_st.py --check` verifies with the official loader. */
static void test_python_interop_file(void) {
  float w[24];
  for (int i = 0; i < 24; i++) w[i] = (float)i / 8.0f;
  int64_t b[3] = {-1, 0, 1};
  uint16_t h[2] = {0x3800, 0xb400};
  uint8_t m[2] = {1, 0}, s = 42;
  spx_st_entry e[] = {{"w", SPX_F32, 3, {2, 3, 4}, w}, {"b", SPX_I64, 1, {3}, b}, {"h", SPX_F16, 1, {2}, h},
                      {"m", SPX_BOOL, 1, {2}, m},      {"s", SPX_U8, 0, {0}, &s}};
  const char *mk[] = {"creator", "step"}, *mv[] = {"smplpix", "17"};
  char path[512];
  spx_t_path(path, sizeof path, "for_python.safetensors");
  CHECK_OK(ctx, spx_st_save(ctx, path, e, 5, mk, mv, 2));
  spx_st_file f;
  CHECK_OK(ctx, spx_st_load(ctx, path, &f));
  spx_st_free(&f);
}

/* Build header-length + header + `data` bytes and parse them from memory. */
static spx_status parse_hdr(const char *json, size_t datalen, uint64_t force_len, int use_force) {
  size_t jl = strlen(json);
  unsigned char *buf = calloc(1, 8 + jl + datalen + 1);
  uint64_t L = use_force ? force_len : (uint64_t)jl;
  for (int i = 0; i < 8; i++) buf[i] = (unsigned char)(L >> (8 * i));
  memcpy(buf + 8, json, jl);
  spx_st_file f;
  spx_status st = spx_st_parse(ctx, "hostile.safetensors", buf, 8 + jl + datalen, &f);
  CHECK(f.tensors == NULL || st == SPX_OK);
  spx_st_free(&f);
  free(buf);
  return st;
}

#define HOSTILE(json, datalen, want)                                                                     \
  do {                                                                                                   \
    spx_status st_ = parse_hdr(json, datalen, 0, 0);                                                     \
    CHECK_MSG(st_ == (want), "%s: got %s (%s)", json, spx_status_name(st_), spx_ctx_message(ctx));      \
    if (st_ != SPX_OK)                                                                                   \
      CHECK_MSG(strstr(spx_ctx_message(ctx), "hostile.safetensors") != NULL, "no name: %s",              \
                spx_ctx_message(ctx));                                                                   \
    if (st_ != SPX_OK) fprintf(stderr, "    %.60s -> %s\n", json, spx_ctx_message(ctx));               \
  } while (0)

static void test_hostile(void) {
  /* sanity: the builder makes valid files */
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8]}}", 8, SPX_OK);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8]}}    ", 8, SPX_OK); /* padding */
  /* header length */
  spx_st_file f;
  CHECK(spx_st_parse(ctx, "hostile.safetensors", "\1\0\0", 3, &f) == SPX_E_FORMAT);
  CHECK(parse_hdr("{}", 0, 1000, 1) == SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "larger than the file") != NULL);
  CHECK(parse_hdr("{}", 0, UINT64_MAX, 1) == SPX_E_FORMAT);
  CHECK(parse_hdr("{}", 0, (uint64_t)200 << 20, 1) == SPX_E_FORMAT);
  CHECK(parse_hdr("{}", 0, 0, 1) == SPX_E_FORMAT);
  /* not a JSON object */
  HOSTILE("[1,2,3]", 0, SPX_E_FORMAT);
  HOSTILE("\"str\"", 0, SPX_E_FORMAT);
  HOSTILE("{\"a\":", 0, SPX_E_FORMAT);
  HOSTILE("{}xyz", 0, SPX_E_FORMAT);
  HOSTILE("{\"a\":1}", 0, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"shape\":[1],\"data_offsets\":[0,4]}}", 4, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"data_offsets\":[0,4]}}", 4, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[1]}}", 4, SPX_E_FORMAT);
  /* offsets */
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,1000]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[8,0]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8,16]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[-8,0]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[0,8]},"
          "\"b\":{\"dtype\":\"F32\",\"shape\":[2],\"data_offsets\":[4,12]}}",
          12, SPX_E_FORMAT); /* overlap */
  CHECK(strstr(spx_ctx_message(ctx), "overlaps") != NULL);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]},"
          "\"b\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[8,12]}}",
          12, SPX_E_FORMAT); /* gap */
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[1],\"data_offsets\":[0,4]}}", 12, SPX_E_FORMAT); /* leftover */
  /* shape / bytes */
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[3],\"data_offsets\":[0,8]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[-2],\"data_offsets\":[0,8]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[1.5],\"data_offsets\":[0,6]}}", 6, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[\"2\"],\"data_offsets\":[0,8]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[1e300],\"data_offsets\":[0,8]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[9007199254740993],\"data_offsets\":[0,8]}}", 8, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F64\",\"shape\":[4294967296,4294967296,4294967296],\"data_offsets\":[0,8]}}", 8,
          SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":\"F64\",\"shape\":[4294967296,1073741824],\"data_offsets\":[0,8]}}", 8,
          SPX_E_FORMAT); /* numel fits, bytes overflow */
  HOSTILE("{\"a\":{\"dtype\":\"U8\",\"shape\":[1,1,1,1,1,1,1,1,1],\"data_offsets\":[0,1]}}", 1, SPX_E_UNSUPPORTED);
  HOSTILE("{\"a\":{\"dtype\":\"F32\",\"shape\":[0,4294967296,4294967296,4294967296],\"data_offsets\":[0,0]}}", 0,
          SPX_OK); /* zero elements: valid */
  /* dtypes */
  HOSTILE("{\"a\":{\"dtype\":\"BF16\",\"shape\":[2],\"data_offsets\":[0,4]}}", 4, SPX_E_UNSUPPORTED);
  CHECK(strstr(spx_ctx_message(ctx), "BF16") != NULL);
  HOSTILE("{\"a\":{\"dtype\":\"Q7\",\"shape\":[2],\"data_offsets\":[0,4]}}", 4, SPX_E_FORMAT);
  HOSTILE("{\"a\":{\"dtype\":7,\"shape\":[2],\"data_offsets\":[0,4]}}", 4, SPX_E_FORMAT);
  /* names */
  HOSTILE("{\"a\":{\"dtype\":\"U8\",\"shape\":[1],\"data_offsets\":[0,1]},"
          "\"a\":{\"dtype\":\"U8\",\"shape\":[1],\"data_offsets\":[1,2]}}",
          2, SPX_E_FORMAT);
  CHECK(strstr(spx_ctx_message(ctx), "duplicate") != NULL);
  /* metadata */
  HOSTILE("{\"__metadata__\":{\"k\":1}}", 0, SPX_E_FORMAT);
  HOSTILE("{\"__metadata__\":[\"k\"]}", 0, SPX_E_FORMAT);
  HOSTILE("{\"__metadata__\":{\"k\":\"v\"},\"__metadata__\":{}}", 0, SPX_E_FORMAT);
  HOSTILE("{\"__metadata__\":{\"k\":\"v\",\"k\":\"w\"}}", 0, SPX_E_FORMAT);
  HOSTILE("{\"__metadata__\":{\"k\":\"v\"}}", 0, SPX_OK);
  /* deep nesting must not blow the stack */
  char deep[20010];
  strcpy(deep, "{\"a\":");
  size_t p = strlen(deep);
  for (int i = 0; i < 10000; i++) deep[p++] = '[';
  deep[p] = 0;
  HOSTILE(deep, 0, SPX_E_FORMAT);
  /* missing / empty files */
  CHECK(spx_st_load(ctx, "/nonexistent/x.safetensors", &f) == SPX_E_IO);
}

static void test_save_errors(void) {
  char path[512];
  spx_t_path(path, sizeof path, "keep.safetensors");
  float v[2] = {1, 2};
  spx_st_entry ok[] = {{"v", SPX_F32, 1, {2}, v}};
  CHECK_OK(ctx, spx_st_save(ctx, path, ok, 1, NULL, NULL, 0));
  spx_st_entry dup[] = {{"v", SPX_F32, 1, {2}, v}, {"v", SPX_F32, 1, {1}, v}};
  spx_st_entry neg[] = {{"v", SPX_F32, 1, {-1}, v}};
  spx_st_entry nul[] = {{"v", SPX_F32, 1, {2}, NULL}};
  spx_st_entry bad[] = {{"v", (spx_dtype)99, 1, {2}, v}};
  spx_st_entry meta[] = {{"__metadata__", SPX_F32, 1, {2}, v}};
  spx_st_entry dims[] = {{"v", SPX_F32, 9, {1}, v}};
  CHECK(spx_st_save(ctx, path, dup, 2, NULL, NULL, 0) == SPX_E_ARG);
  CHECK(spx_st_save(ctx, path, neg, 1, NULL, NULL, 0) == SPX_E_ARG);
  CHECK(spx_st_save(ctx, path, nul, 1, NULL, NULL, 0) == SPX_E_ARG);
  CHECK(spx_st_save(ctx, path, bad, 1, NULL, NULL, 0) == SPX_E_ARG);
  CHECK(spx_st_save(ctx, path, meta, 1, NULL, NULL, 0) == SPX_E_ARG);
  CHECK(spx_st_save(ctx, path, dims, 1, NULL, NULL, 0) == SPX_E_ARG);
  const char *k2[] = {"a", "a"}, *v2[] = {"x", "y"};
  CHECK(spx_st_save(ctx, path, ok, 1, k2, v2, 2) == SPX_E_ARG);
  CHECK(spx_st_save(ctx, "/nonexistent/dir/w.safetensors", ok, 1, NULL, NULL, 0) == SPX_E_IO);
  /* the earlier file is intact */
  spx_st_file f;
  CHECK_OK(ctx, spx_st_load(ctx, path, &f));
  CHECK(f.count == 1 && f.tensors && f.tensors[0].nbytes == 8);
  spx_st_free(&f);
}

int main(void) {
  if (spx_ctx_create(&ctx) != SPX_OK) return 1;
  SPX_RUN(test_roundtrip);
  SPX_RUN(test_reference_file);
  SPX_RUN(test_python_interop_file);
  SPX_RUN(test_hostile);
  SPX_RUN(test_save_errors);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
