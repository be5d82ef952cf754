/* OBJ: round trips, the statement/corner forms, 0-1 and 0-255 colors, and bad inputs (exact
 * status, a message naming the file and line, the output left empty), atomic saves. */
#include "io_common.h"
#include "smplpix/mesh.h"

static spx_ctx *ctx;

static spx_status parse(const char *name, const char *text, spx_mesh *m) {
  return spx_mesh_parse_obj(ctx, name, text, strlen(text), m);
}

static void test_roundtrip(void) {
  for (int attrs = 0; attrs < 2; attrs++) {
    spx_mesh m, r;
    t_grid_mesh(&m, attrs);
    char p[512];
    spx_t_path(p, sizeof p, attrs ? "rt_attrs.obj" : "rt_plain.obj");
    CHECK_OK(ctx, spx_mesh_save(ctx, p, &m, SPX_MESH_AUTO));
    CHECK_OK(ctx, spx_mesh_load(ctx, p, &r));
    CHECK(r.nv == m.nv && r.nf == m.nf && r.nuv == m.nuv);
    CHECK(t_maxdiff(r.pos, m.pos, 27) == 0); /* %.9g round-trips floats exactly */
    CHECK(t_maxdiff(r.col, m.col, attrs ? 27 : 0) == 0);
    CHECK(t_maxdiff(r.nrm, m.nrm, attrs ? 27 : 0) == 0);
    CHECK(t_maxdiff(r.uv, m.uv, attrs ? 18 : 0) == 0);
    CHECK(t_ints_equal(r.faces, m.faces, 24));
    CHECK(t_ints_equal(r.face_uv, m.face_uv, 24));
    spx_mesh_free(&r);
    spx_mesh_free(&m);
  }
  /* a colored point cloud */
  spx_mesh m, r;
  t_grid_mesh(&m, 1);
  free(m.faces);
  free(m.face_uv);
  free(m.uv);
  m.faces = m.face_uv = NULL;
  m.uv = NULL;
  m.nf = m.nuv = 0;
  char p[512];
  spx_t_path(p, sizeof p, "cloud.obj");
  CHECK_OK(ctx, spx_mesh_save(ctx, p, &m, SPX_MESH_OBJ));
  CHECK_OK(ctx, spx_mesh_load(ctx, p, &r));
  CHECK(r.nv == 9 && r.nf == 0 && r.faces == NULL && t_maxdiff(r.col, m.col, 27) == 0 && t_maxdiff(r.nrm, m.nrm, 27) == 0);
  spx_mesh_free(&r);
  spx_mesh_free(&m);
}

static void test_forms(void) {
  spx_mesh m;
  /* quad + pentagon fan-triangulated, negative indices, comments and ignored statements */
  const char *t = "# comment\nmtllib a.mtl\no thing\ng grp\ns off\nusemtl red\n"
                  "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 # trailing comment\n\t v 0.5 2 0\r\n"
                  "f 1 2 3 4\nf -5 -4 -3 -2 -1\n";
  CHECK_OK(ctx, parse("forms.obj", t, &m));
  CHECK(m.nv == 5 && m.nf == 5 && m.col == NULL && m.nrm == NULL && m.uv == NULL);
  if (m.nf == 5) {
    int32_t want[15] = {0, 1, 2, 0, 2, 3, 0, 1, 2, 0, 2, 3, 0, 3, 4};
    CHECK(t_ints_equal(m.faces, want, 15));
  }
  spx_mesh_free(&m);
  /* v/vt/vn and v//vn */
  t = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.5\nvt 1 0\nvt 0 1 0\nvn 0 0 1\nvn 0 1 0\n"
      "f 1/1/1 2/2/1 3/3/2\n";
  CHECK_OK(ctx, parse("vtvn.obj", t, &m));
  CHECK(m.nuv == 3 && m.face_uv && m.face_uv[0] == 0 && m.face_uv[2] == 2 && m.uv[0] == 0.25f && m.uv[1] == 0.5f);
  CHECK(m.nrm && m.nrm[2] == 1.0f && m.nrm[5] == 1.0f && m.nrm[7] == 1.0f && m.nrm[8] == 0.0f);
  spx_mesh_free(&m);
  t = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 1 0 0\nf 1//1 2//1 3//-1\n";
  CHECK_OK(ctx, parse("vvn.obj", t, &m));
  CHECK(m.nrm && m.nrm[0] == 1.0f && m.nrm[6] == 1.0f && m.face_uv == NULL);
  spx_mesh_free(&m);
  /* colors 0-255 (detected because one component > 1) and 0-1 */
  t = "v 0 0 0 255 0 51\nv 1 0 0 0 1 0\nv 0 1 0 1 1 1\nf 1 2 3\n";
  CHECK_OK(ctx, parse("c255.obj", t, &m));
  CHECK(m.col && m.col[0] == 1.0f && m.col[2] == 51.0f / 255.0f && m.col[4] == 1.0f / 255.0f);
  spx_mesh_free(&m);
  t = "v 0 0 0 1 0 0.5\nv 1 0 0 0 1 0\nv 0 1 0 1 1 1\nf 1 2 3\n";
  CHECK_OK(ctx, parse("c01.obj", t, &m));
  CHECK(m.col && m.col[0] == 1.0f && m.col[2] == 0.5f && m.col[4] == 1.0f);
  spx_mesh_free(&m);
  /* the body mesh */
  char p[512];
  snprintf(p, sizeof p, "%s/body/human_woman.obj", SPX_REPO_DATA);
  CHECK_OK(ctx, spx_mesh_load(ctx, p, &m));
  CHECK(m.nv == 6890 && m.nf == 13776);
  spx_mesh_free(&m);
}

static void test_bad(void) {
  spx_mesh m;
  struct {
    const char *text, *needle;
    spx_status st;
  } cases[] = {
      {"v 0 0 0\nv 1 0\n", "bad.obj:2", SPX_E_FORMAT},                          /* truncated vertex */
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n", "bad.obj:4", SPX_E_FORMAT},        /* 2-vertex face */
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "bad.obj:4", SPX_E_FORMAT},      /* index out of range */
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", "bad.obj:4", SPX_E_FORMAT},      /* index 0 */
      {"v 0 0 0\nf -2 1 1\nv 1 0 0\n", "bad.obj:2", SPX_E_FORMAT},              /* relative before defined */
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3x\n", "bad.obj:4", SPX_E_FORMAT},     /* junk in a corner */
      {"v 0 0 0\nv nan 0 0\n", "bad.obj:2", SPX_E_NUMERIC},                     /* NaN */
      {"v 0 0 0\nv 1 inf 0\n", "bad.obj:2", SPX_E_NUMERIC},                     /* Inf */
      {"v 0 0 0\nv 1e39 0 0\n", "bad.obj:2", SPX_E_NUMERIC},                    /* overflows float */
      {"v 0 0 0 300 0 0\n", "bad.obj:1", SPX_E_FORMAT},                         /* color > 255 */
      {"v 0 0 0\nxyz 1\n", "bad.obj:2", SPX_E_FORMAT},                          /* unknown statement */
      {"\x7f" "ELF\x02\x01\x01\n\x01\x02", "bad.obj:1", SPX_E_FORMAT},          /* garbage */
      {"# nothing\n", "no vertices", SPX_E_FORMAT},                             /* empty */
      {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2 3\n", "bad.obj:5", SPX_E_FORMAT}, /* mixed vt */
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    memset(&m, 0x55, sizeof m);
    spx_status st = parse("bad.obj", cases[i].text, &m);
    CHECK_MSG(st == cases[i].st, "case %zu: %s (%s)", i, spx_status_name(st), spx_ctx_message(ctx));
    CHECK_MSG(strstr(spx_ctx_message(ctx), cases[i].needle) != NULL, "case %zu: '%s' lacks '%s'", i,
              spx_ctx_message(ctx), cases[i].needle);
    CHECK(t_is_zero(&m, sizeof m));
  }
  /* embedded NUL */
  CHECK_ERR(ctx, spx_mesh_parse_obj(ctx, "nul.obj", "v 0 0 0\nv 0\0 0 0\n", 16, &m), SPX_E_FORMAT, "nul.obj:2", "NUL");
  /* every prefix of a good file either parses or fails cleanly (no crash / leak under ASan) */
  const char *good = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nv 0 1 0 0 0 1\nf 1/1 2/2 3/3\n";
  for (size_t k = 0; k < strlen(good); k++) {
    if (spx_mesh_parse_obj(ctx, "prefix.obj", good, k, &m) == SPX_OK) spx_mesh_free(&m);
    else CHECK(t_is_zero(&m, sizeof m));
  }
  CHECK_ERR(ctx, spx_mesh_load(ctx, "/nonexistent/a.obj", &m), SPX_E_IO, "/nonexistent/a.obj", NULL);
  CHECK_ERR(ctx, spx_mesh_load(ctx, "a.stl", &m), SPX_E_UNSUPPORTED, "a.stl", NULL);
}

static void test_failed_save(void) {
  spx_mesh m;
  char p[512];
  t_failed_save_start(ctx, "obj", 0, &m, p, sizeof p);
  m.pos[4] = NAN; /* refused before anything is written */
  CHECK_ERR(ctx, spx_mesh_save(ctx, p, &m, SPX_MESH_AUTO), SPX_E_NUMERIC, "keep.obj", "vertex 1");
  CHECK(t_file_equals(p, "previous", 8));
  m.pos[4] = 0;
  m.faces[5] = 9; /* index out of range */
  CHECK_ERR(ctx, spx_mesh_save(ctx, p, &m, SPX_MESH_AUTO), SPX_E_FORMAT, "keep.obj", "face 1");
  CHECK(t_file_equals(p, "previous", 8));
  spx_mesh_free(&m);
}

int main(void) {
  const spx_t_test tests[] = {SPX_TEST(test_roundtrip), SPX_TEST(test_forms), SPX_TEST(test_bad),
                               SPX_TEST(test_failed_save)};
  return spx_t_main_ctx(&ctx, 0, tests, 4);
}
