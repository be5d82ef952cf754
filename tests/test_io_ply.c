/* PLY: ascii and binary round trips, all scalar types and aliases, unknown elements skipped in
 * both encodings, lying headers (counts, list lengths), unknown types, big endian, NaN/Inf,
 * truncation; errors name the file and the problem and leave the output empty. */
#include "io_common.h"
#include "smplpix/mesh.h"

static spx_ctx *ctx;

/* byte buffer for building binary files */
typedef struct {
  unsigned char b[8192];
  size_t n;
} tbuf;
static void put(tbuf *t, const void *p, size_t n) {
  memcpy(t->b + t->n, p, n);
  t->n += n;
}
static void puts_(tbuf *t, const char *s) { put(t, s, strlen(s)); }
static void put_f32(tbuf *t, float v) { put(t, &v, 4); } /* little-endian host */
static void put_f64(tbuf *t, double v) { put(t, &v, 8); }
static void put_u8(tbuf *t, unsigned v) {
  unsigned char c = (unsigned char)v;
  put(t, &c, 1);
}
static void put_i16(tbuf *t, int v) {
  int16_t x = (int16_t)v;
  put(t, &x, 2);
}
static void put_u16(tbuf *t, unsigned v) {
  uint16_t x = (uint16_t)v;
  put(t, &x, 2);
}
static void put_i32(tbuf *t, int32_t v) { put(t, &v, 4); }
static void put_u32(tbuf *t, uint32_t v) { put(t, &v, 4); }

static void test_roundtrip(void) {
  for (int fmt = SPX_MESH_PLY_ASCII; fmt <= SPX_MESH_PLY_BINARY; fmt++)
    for (int attrs = 0; attrs < 2; attrs++) {
      spx_mesh m, r;
      t_grid_mesh(&m, attrs);
      char p[512];
      snprintf(p, sizeof p, "%s/rt_%d_%d.PLY", spx_t_tmpdir(), fmt, attrs); /* extension case-insensitive */
      CHECK_OK(ctx, spx_mesh_save(ctx, p, &m, (spx_mesh_format)fmt));
      CHECK_OK(ctx, spx_mesh_load(ctx, p, &r));
      CHECK(r.nv == m.nv && r.nf == m.nf && r.nuv == m.nuv);
      CHECK(t_maxdiff(r.pos, m.pos, 27) == 0);
      CHECK(t_maxdiff(r.nrm, m.nrm, attrs ? 27 : 0) == 0);
      CHECK(t_maxdiff(r.uv, m.uv, attrs ? 18 : 0) == 0);
      CHECK(t_maxdiff(r.col, m.col, attrs ? 27 : 0) <= 0.5 / 255 + 1e-7); /* 8-bit colors */
      CHECK(t_ints_equal(r.faces, m.faces, 24));
      CHECK(t_ints_equal(r.face_uv, m.face_uv, 24));
      spx_mesh_free(&r);
      spx_mesh_free(&m);
    }
  /* per-corner UVs (nuv != nv) travel as a face texcoord list */
  for (int fmt = SPX_MESH_PLY_ASCII; fmt <= SPX_MESH_PLY_BINARY; fmt++) {
    spx_mesh m, r;
    t_grid_mesh(&m, 1);
    free(m.uv);
    m.nuv = 24;
    m.uv = malloc(48 * sizeof(float));
    for (int i = 0; i < 48; i++) m.uv[i] = (float)i / 47.0f;
    for (int i = 0; i < 24; i++) m.face_uv[i] = 23 - i;
    char p[512];
    snprintf(p, sizeof p, "%s/corner_uv_%d.ply", spx_t_tmpdir(), fmt);
    CHECK_OK(ctx, spx_mesh_save(ctx, p, &m, (spx_mesh_format)fmt));
    CHECK_OK(ctx, spx_mesh_load(ctx, p, &r));
    CHECK(r.nf == 8 && r.nuv == 24 && r.face_uv && r.uv);
    if (r.face_uv && r.uv && r.nf == 8) {
      int same = 1;
      for (int c = 0; c < 24; c++)
        for (int k = 0; k < 2; k++) same &= r.uv[r.face_uv[c] * 2 + k] == m.uv[m.face_uv[c] * 2 + k];
      CHECK(same);
    }
    spx_mesh_free(&r);
    spx_mesh_free(&m);
  }
  /* AUTO on .ply writes binary little endian */
  spx_mesh m;
  t_grid_mesh(&m, 0);
  char p[512];
  spx_t_path(p, sizeof p, "auto.ply");
  CHECK_OK(ctx, spx_mesh_save(ctx, p, &m, SPX_MESH_AUTO));
  unsigned char *d;
  size_t n;
  if (spx_read_file(ctx, p, 1 << 20, &d, &n) == SPX_OK) {
    CHECK(strstr((char *)d, "format binary_little_endian 1.0\n") != NULL);
    free(d);
  }
  spx_mesh_free(&m);
}

/* Binary file: an unknown element (every scalar type + a list) first, then faces, then
 * vertices with double coordinates, ushort colors, int8-named extra property, float s/t. */
static void test_binary_types_and_order(void) {
  tbuf t = {{0}, 0};
  puts_(&t, "ply\r\nformat binary_little_endian 1.0\r\ncomment x\r\nobj_info y\r\n"
            "element junk 2\r\nproperty char a\r\nproperty uchar b\r\nproperty short c\r\nproperty ushort d\r\n"
            "property int e\r\nproperty uint f\r\nproperty float g\r\nproperty double h\r\n"
            "property list uint16 float64 stuff\r\n"
            "element face 2\r\nproperty list uint int32 vertex_index\r\nproperty uint8 flags\r\n"
            "element vertex 4\r\nproperty float64 x\r\nproperty float64 y\r\nproperty float64 z\r\n"
            "property int8 extra\r\nproperty ushort red\r\nproperty ushort green\r\nproperty ushort blue\r\n"
            "property float32 u\r\nproperty float32 v\r\nend_header\r\n");
  for (int r = 0; r < 2; r++) {
    put_u8(&t, 0x80);
    put_u8(&t, 7);
    put_i16(&t, -5);
    put_u16(&t, 65535);
    put_i32(&t, -7);
    put_u32(&t, 0xffffffffu);
    put_f32(&t, NAN); /* an unused property may hold anything */
    put_f64(&t, 1e300);
    put_u16(&t, (unsigned)(r + 1));
    for (int k = 0; k <= r; k++) put_f64(&t, (double)k);
  }
  put_u32(&t, 4); /* a quad */
  for (int k = 0; k < 4; k++) put_i32(&t, k);
  put_u8(&t, 1);
  put_u32(&t, 3);
  put_i32(&t, 3);
  put_i32(&t, 2);
  put_i32(&t, 1);
  put_u8(&t, 2);
  for (int v = 0; v < 4; v++) {
    put_f64(&t, 0.1 * v);
    put_f64(&t, -1.0 / 3.0);
    put_f64(&t, 1e-3);
    put_u8(&t, 0x7f);
    put_u16(&t, 65535);
    put_u16(&t, 0);
    put_u16(&t, (unsigned)(v * 1000));
    put_f32(&t, 0.25f * (float)v);
    put_f32(&t, 1.0f);
  }
  spx_mesh m;
  CHECK_OK(ctx, spx_mesh_parse_ply(ctx, "types.ply", t.b, t.n, &m));
  CHECK(m.nv == 4 && m.nf == 3);
  if (m.nf == 3) {
    int32_t want[9] = {0, 1, 2, 0, 2, 3, 3, 2, 1};
    CHECK(t_ints_equal(m.faces, want, 9));
  }
  CHECK(m.pos && m.pos[3] == (float)0.1 && m.pos[4] == (float)(-1.0 / 3.0) && m.pos[5] == (float)1e-3);
  CHECK(m.col && m.col[0] == 1.0f && m.col[1] == 0.0f && m.col[11] == (float)(3000.0 / 65535.0));
  CHECK(m.uv && m.nuv == 4 && m.uv[6] == 0.75f && m.uv[7] == 1.0f && t_ints_equal(m.face_uv, m.faces, 9));
  CHECK(m.nrm == NULL);
  spx_mesh_free(&m);
  /* every truncation fails cleanly */
  int all_fail = 1;
  for (size_t k = 0; k < t.n; k++) {
    if (spx_mesh_parse_ply(ctx, "cut.ply", t.b, k, &m) == SPX_OK) {
      all_fail = 0;
      spx_mesh_free(&m);
    } else if (!t_is_zero(&m, sizeof m)) {
      all_fail = 0;
    }
  }
  CHECK(all_fail);
}

static void test_ascii_forms(void) {
  const char *t = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                  "property float nx\nproperty float ny\nproperty float nz\n"
                  "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                  "element edge 1\nproperty int vertex1\nproperty list uchar int extra\n"
                  "element face 1\nproperty list uchar uint vertex_indices\nend_header\n"
                  "0 0 0 0 0 1 255 0 51\n1 0 0 0 0 1 0 0 0\n0 1 0 0 0 1 10 20 30\n"
                  "0 3 7 8 9\n"
                  "3 0 1 2\n";
  spx_mesh m;
  CHECK_OK(ctx, spx_mesh_parse_ply(ctx, "ascii.ply", t, strlen(t), &m));
  CHECK(m.nv == 3 && m.nf == 1 && m.nrm && m.nrm[2] == 1.0f && m.col && m.col[0] == 1.0f &&
        m.col[2] == (float)(51.0 / 255.0) && m.uv == NULL);
  spx_mesh_free(&m);
  /* float colors are taken as they are; a point cloud without faces */
  t = "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\n"
      "property float red\nproperty float green\nproperty float blue\nend_header\n1 2 3 0.5 0.25 1\n4 5 6 0 0 0";
  CHECK_OK(ctx, spx_mesh_parse_ply(ctx, "cloud.ply", t, strlen(t), &m));
  CHECK(m.nv == 2 && m.nf == 0 && m.faces == NULL && m.col && m.col[1] == 0.25f && m.pos[5] == 6.0f);
  spx_mesh_free(&m);
}

static void test_bad(void) {
  struct {
    const char *text, *n1, *n2;
    spx_status st;
  } cases[] = {
      /* lying counts, refused before allocating */
      {"ply\nformat ascii 1.0\nelement vertex 2000000000\nproperty float x\nproperty float y\nproperty float z\n"
       "end_header\n0 0 0\n",
       "vertex", "claims", SPX_E_FORMAT},
      {"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
       "end_header\n0123456789012345678901234567890123456789",
       "vertex", "claims", SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
       "element face 1\nproperty list uint int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n",
       "list length", NULL, SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float16 x\nend_header\n", "unknown property type", "'float16'",
       SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement face 3\nproperty list half int vertex_indices\nend_header\n",
       "unknown property type", "'half'", SPX_E_FORMAT},
      {"ply\nformat binary_big_endian 1.0\nelement vertex 0\nend_header\n", "binary_big_endian", "not supported",
       SPX_E_UNSUPPORTED},
      {"PLY\nformat ascii 1.0\n", "not a PLY", NULL, SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", "end_header", NULL, SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n", "'z'", NULL,
       SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
       "0 0 0\n0 nan 0\n",
       "vertex 1", "not finite", SPX_E_NUMERIC},
      {"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
       "0 0 0\n0 0 inf\n",
       "vertex 1", "not finite", SPX_E_NUMERIC},
      {"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
       "0 0 0\n0 0 abc\n",
       ":9:", "expected a number", SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
       "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
       "vertex index 3", "out of range", SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
       "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n",
       "face with 2 vertices", NULL, SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
       "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n0 0 0 1 2 3\n1 0 0 1 2 3\n0 1 0 1 2 300\n",
       ":13:", "integer", SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
       "property uchar x\nend_header\n",
       "declared twice", NULL, SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar float x\nend_header\n", "must not be a list", NULL,
       SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement blob 5\nend_header\n", "no properties", NULL, SPX_E_FORMAT},
      /* every byte belongs to a declared element; the only version is 1.0 */
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
       "0 0 0\n1 0 0\n",
       ":9:", "data after the last element", SPX_E_FORMAT},
      {"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty uchar x\nproperty uchar y\nproperty uchar z\n"
       "end_header\nabcde",
       "2 bytes after the last element", NULL, SPX_E_FORMAT},
      {"ply\nformat ascii 2.0\nelement vertex 0\nend_header\n", "version '2.0'", NULL, SPX_E_UNSUPPORTED},
      {"ply\nformat ascii\nelement vertex 0\nend_header\n", ":2:", "format TYPE 1.0", SPX_E_FORMAT},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
       "element face 1\nproperty list uchar int vertex_indices\nproperty list uchar float texcoord\nend_header\n"
       "0 0 0\n1 0 0\n0 1 0\n3 0 1 2 4 0 0 1 0\n",
       ":14:", "texcoord list has 4 values for a face with 3 corners", SPX_E_FORMAT},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    spx_mesh m;
    memset(&m, 0x55, sizeof m);
    spx_status st = spx_mesh_parse_ply(ctx, "bad.ply", cases[i].text, strlen(cases[i].text), &m);
    const char *msg = spx_ctx_message(ctx);
    CHECK_MSG(st == cases[i].st, "case %zu: %s (%s)", i, spx_status_name(st), msg);
    CHECK_MSG(strncmp(msg, "bad.ply", 7) == 0 && t_has(msg, cases[i].n1) && t_has(msg, cases[i].n2),
              "case %zu: '%s' lacks '%s'/'%s'", i, msg, cases[i].n1, t_s(cases[i].n2));
    CHECK(t_is_zero(&m, sizeof m));
  }
  /* binary: NaN coordinate, lying list length */
  tbuf t = {{0}, 0};
  puts_(&t, "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list int int vertex_indices\nend_header\n");
  size_t hdr = t.n;
  for (int k = 0; k < 9; k++) put_f32(&t, k == 4 ? NAN : (float)k);
  put_i32(&t, 3);
  put_i32(&t, 0);
  put_i32(&t, 1);
  put_i32(&t, 2);
  spx_mesh m;
  CHECK_ERR(ctx, spx_mesh_parse_ply(ctx, "nan.ply", t.b, t.n, &m), SPX_E_NUMERIC, "nan.ply", "vertex 1");
  CHECK(t_is_zero(&m, sizeof m));
  float one = 1;
  memcpy(t.b + hdr + 16, &one, 4);
  CHECK_OK(ctx, spx_mesh_parse_ply(ctx, "ok.ply", t.b, t.n, &m));
  spx_mesh_free(&m);
  int32_t lie = 1 << 30;
  memcpy(t.b + hdr + 36, &lie, 4);
  CHECK_ERR(ctx, spx_mesh_parse_ply(ctx, "lie.ply", t.b, t.n, &m), SPX_E_FORMAT, "lie.ply", "list length");
  lie = -3;
  memcpy(t.b + hdr + 36, &lie, 4);
  CHECK_ERR(ctx, spx_mesh_parse_ply(ctx, "neg.ply", t.b, t.n, &m), SPX_E_FORMAT, "neg.ply", "negative");
  CHECK(t_is_zero(&m, sizeof m));
}

static void test_failed_save(void) {
  spx_mesh m;
  char p[512];
  t_failed_save_start(ctx, "ply", 1, &m, p, sizeof p);
  m.col[5] = INFINITY;
  CHECK_ERR(ctx, spx_mesh_save(ctx, p, &m, SPX_MESH_PLY_ASCII), SPX_E_NUMERIC, "keep.ply", "color of vertex 1");
  CHECK(t_file_equals(p, "previous", 8));
  spx_mesh_free(&m);
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_roundtrip), SPX_TEST(test_binary_types_and_order),
                               SPX_TEST(test_ascii_forms), SPX_TEST(test_bad), SPX_TEST(test_failed_save)};
  return spx_t_main_ctx(&ctx, 0, tests, 5);
}
