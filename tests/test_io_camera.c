/* Camera JSON: parse one object / an array, save → load round trip (bit exact), look_at
 * geometry, and every validation rule with its status and "file: [i].key: problem" message. */
#include "io_common.h"
#include "smplpix/camera.h"

static spx_ctx *ctx;

static const char *good =
    "{\"width\": 410, \"height\": 308, \"K\": [[500.5, 0, 205], [0, 501, 154], [0, 0, 1]],"
    " \"R\": [[1, 0, 0], [0, -1, 0], [0, 0, -1]], \"t\": [0.1, -0.2, 3]}";

static int cams_equal(const spx_camera *a, const spx_camera *b, int n) {
  for (int i = 0; i < n; i++) {
    if (a[i].width != b[i].width || a[i].height != b[i].height) return 0;
    for (int r = 0; r < 3; r++) {
      if (a[i].t[r] != b[i].t[r]) return 0; /* == : -0.0 is written as 0 */
      for (int k = 0; k < 3; k++)
        if (a[i].K[r][k] != b[i].K[r][k] || a[i].R[r][k] != b[i].R[r][k]) return 0;
    }
  }
  return 1;
}

static spx_status parse(const char *name, const char *text, spx_camera **c, int *n) {
  return spx_camera_parse(ctx, name, text, strlen(text), c, n);
}

static void test_parse_and_roundtrip(void) {
  spx_camera *c = NULL, *r = NULL;
  int n = 0, rn = 0;
  CHECK_OK(ctx, parse("one.json", good, &c, &n));
  CHECK(n == 1 && c && c[0].width == 410 && c[0].height == 308 && c[0].K[0][0] == 500.5 && c[0].K[1][2] == 154 &&
        c[0].R[1][1] == -1 && c[0].t[2] == 3);
  free(c);
  char arr[2048];
  snprintf(arr, sizeof arr, "[%s, %s]", good, good);
  CHECK_OK(ctx, parse("two.json", arr, &c, &n));
  CHECK(n == 2 && c && c[1].t[0] == 0.1);
  if (n == 2) {
    double eye[3] = {0.3, 1.2, -2.5}, target[3] = {0, 1, 0}, up[3] = {0, 1, 0};
    CHECK_OK(ctx, spx_camera_look_at(ctx, 640, 480, 1000.0 / 3.0, eye, target, up, &c[1]));
    char p[512];
    spx_t_path(p, sizeof p, "cams.json");
    CHECK_OK(ctx, spx_camera_save(ctx, p, c, 2));
    CHECK_OK(ctx, spx_camera_load(ctx, p, &r, &rn));
    CHECK(rn == 2 && r && cams_equal(r, c, 2)); /* doubles survive exactly */
    free(r);
    spx_t_path(p, sizeof p, "cam1.json");
    CHECK_OK(ctx, spx_camera_save(ctx, p, c, 1));
    CHECK_OK(ctx, spx_camera_load(ctx, p, &r, &rn));
    CHECK(rn == 1 && r && cams_equal(r, c, 1));
    unsigned char *d;
    size_t dn;
    if (spx_read_file(ctx, p, 1 << 20, &d, &dn) == SPX_OK) {
      CHECK(d[0] == '{'); /* count 1 writes an object */
      free(d);
    }
    free(r);
  }
  free(c);
}

/* project a world point with (u', v', d) = K (R x + t) */
static void project(const spx_camera *c, const double x[3], double *u, double *v, double *d) {
  double cam[3], img[3];
  for (int i = 0; i < 3; i++) cam[i] = c->R[i][0] * x[0] + c->R[i][1] * x[1] + c->R[i][2] * x[2] + c->t[i];
  for (int i = 0; i < 3; i++) img[i] = c->K[i][0] * cam[0] + c->K[i][1] * cam[1] + c->K[i][2] * cam[2];
  *d = img[2];
  *u = img[0] / img[2];
  *v = img[1] / img[2];
}

static void test_look_at(void) {
  spx_camera c;
  double eye[3] = {0, 1, 3}, target[3] = {0, 1, 0}, up[3] = {0, 1, 0};
  CHECK_OK(ctx, spx_camera_look_at(ctx, 400, 300, 500, eye, target, up, &c));
  CHECK_OK(ctx, spx_camera_validate(ctx, "look_at", &c));
  double u, v, d;
  project(&c, target, &u, &v, &d); /* the target lands in the image centre, 3 units ahead */
  CHECK_NEAR(u, 200, 1e-9, 0);
  CHECK_NEAR(v, 150, 1e-9, 0);
  CHECK_NEAR(d, 3, 1e-12, 0);
  double above[3] = {0, 1.5, 0};
  project(&c, above, &u, &v, &d); /* world up is image up (smaller row) */
  CHECK(v < 150 && fabs(u - 200) < 1e-9);
  /* camera on +z looking toward -z with y up: world +x appears on the image's right */
  double right[3] = {0.5, 1, 0};
  project(&c, right, &u, &v, &d);
  CHECK(u > 200);
  CHECK_ERR(ctx, spx_camera_look_at(ctx, 400, 300, 500, eye, eye, up, &c), SPX_E_ARG, "look_at", "coincide");
  double fwd_up[3] = {0, 0, 1};
  CHECK_ERR(ctx, spx_camera_look_at(ctx, 400, 300, 500, eye, target, fwd_up, &c), SPX_E_ARG, "look_at", "parallel");
  CHECK_ERR(ctx, spx_camera_look_at(ctx, 0, 300, 500, eye, target, up, &c), SPX_E_CAMERA, "width", NULL);
}

static void test_bad(void) {
  struct {
    const char *text, *n1, *n2;
    spx_status st;
  } cases[] = {
      {"{\"height\": 308, \"K\": [[1,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,0]}",
       "cam.json: width: expected an integer", "missing", SPX_E_FORMAT},
      {"[{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,0]},"
       " {\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]]}]",
       "cam.json: [1].t: expected an array of 3 numbers", "missing", SPX_E_FORMAT},
      {"[{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0]}]",
       "cam.json: [0].t: expected an array of 3 numbers", NULL, SPX_E_FORMAT},
      {"{\"width\": \"4\", \"height\": 3}", "cam.json: width: expected an integer", NULL, SPX_E_FORMAT},
      {"{\"width\": 4.5, \"height\": 3}", "cam.json: width: expected an integer", NULL, SPX_E_FORMAT},
      {"{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,\"0\",1]]}", "cam.json: K: expected a number", NULL,
       SPX_E_FORMAT},
      {"{\"width\": 4, \"height\": 3, \"K\": [1,0,0,0,1,0,0,0,1]}", "cam.json: K: expected a 3x3 array", NULL, SPX_E_FORMAT},
      {"{\"width\": 0, \"height\": 3}", "cam.json: width: 0 is outside 1..16384", NULL, SPX_E_CAMERA},
      {"{\"width\": 4, \"height\": 20000}", "cam.json: height: 20000 is outside 1..16384", NULL, SPX_E_CAMERA},
      {"{\"width\": 4, \"height\": 3, \"K\": [[0,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,0]}",
       "cam.json: K: focal lengths must be positive", NULL, SPX_E_CAMERA},
      {"{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,1,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,0]}",
       "cam.json: K: not upper-triangular", NULL, SPX_E_CAMERA},
      {"{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,0,2]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,0]}",
       "cam.json: K: K[2][2]", NULL, SPX_E_CAMERA},
      {"[{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,0,0]},"
       "{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0.01,0],[0,1,0],[0,0,1]], \"t\": [0,0,0]}]",
       "cam.json: [1].R: not orthonormal", NULL, SPX_E_CAMERA},
      {"{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,-1]], \"t\": [0,0,0]}",
       "cam.json: R: determinant", NULL, SPX_E_CAMERA},
      {"{\"width\": 4, \"height\": 3, \"K\": [[1,0,0],[0,1,0],[0,0,1]], \"R\": [[1,0,0],[0,1,0],[0,0,1]], \"t\": [0,1e999,0]}",
       "cam.json: t: value is not finite", NULL, SPX_E_NUMERIC},
      {"[]", "cam.json: empty camera array", NULL, SPX_E_FORMAT},
      {"[1]", "cam.json: [0]: expected a camera object", NULL, SPX_E_FORMAT},
      {"\"x\"", "cam.json: expected a camera object", NULL, SPX_E_FORMAT},
      {"{\"width\": 4,", "cam.json: invalid JSON", NULL, SPX_E_FORMAT},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    spx_camera *c = (spx_camera *)&c;
    int n = 77;
    spx_status st = parse("cam.json", cases[i].text, &c, &n);
    const char *msg = spx_ctx_message(ctx);
    CHECK_MSG(st == cases[i].st, "case %zu: %s (%s)", i, spx_status_name(st), msg);
    CHECK_MSG(t_has(msg, cases[i].n1) && t_has(msg, cases[i].n2), "case %zu: '%s' lacks '%s'/'%s'", i, msg, cases[i].n1,
              t_s(cases[i].n2));
    CHECK(c == NULL && n == 0);
  }
  /* R orthonormal within 1e-4 is accepted */
  spx_camera cam;
  memset(&cam, 0, sizeof cam);
  cam.width = cam.height = 16384;
  cam.K[0][0] = cam.K[1][1] = cam.K[2][2] = 1;
  cam.R[0][0] = cam.R[1][1] = cam.R[2][2] = 1;
  cam.R[0][1] = 5e-5;
  CHECK_OK(ctx, spx_camera_validate(ctx, "mem", &cam));
  cam.R[0][1] = 2e-4;
  CHECK_ERR(ctx, spx_camera_validate(ctx, "mem", &cam), SPX_E_CAMERA, "mem: R: not orthonormal", NULL);
  cam.R[0][1] = 0;
  cam.K[0][1] = NAN;
  CHECK_ERR(ctx, spx_camera_validate(ctx, "mem", &cam), SPX_E_NUMERIC, "mem: K: value is not finite", NULL);
  spx_camera *c;
  int n;
  CHECK_ERR(ctx, spx_camera_load(ctx, "/nonexistent/cam.json", &c, &n), SPX_E_IO, "/nonexistent/cam.json", NULL);
}

static void test_failed_save(void) {
  spx_camera *c = NULL;
  int n = 0;
  CHECK_OK(ctx, parse("one.json", good, &c, &n));
  if (!c) return;
  CHECK_ERR(ctx, spx_camera_save(ctx, "/nonexistent-dir/c.json", c, 1), SPX_E_IO, "/nonexistent-dir/c.json", NULL);
  CHECK(!spx_t_file_exists("/nonexistent-dir/c.json"));
  char p[512];
  spx_t_path(p, sizeof p, "keep.json");
  CHECK(t_write_file(p, "previous", 8));
  c[0].R[0][0] = 2; /* invalid: refused, nothing written */
  CHECK_ERR(ctx, spx_camera_save(ctx, p, c, 1), SPX_E_CAMERA, "keep.json: R: not orthonormal", NULL);
  CHECK(t_file_equals(p, "previous", 8));
  free(c);
}

int main(void) {
  if (spx_ctx_create(&ctx) != SPX_OK) return 1;
  SPX_RUN(test_parse_and_roundtrip);
  SPX_RUN(test_look_at);
  SPX_RUN(test_bad);
  SPX_RUN(test_failed_save);
  spx_ctx_destroy(ctx);
  return spx_test_summary();
}
