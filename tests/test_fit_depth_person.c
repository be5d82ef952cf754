/* spx_fit_depth_person: the person in a raw depth frame (tests/fit_view.h's view_room_depth: a
 * posed body standing in a room, floor and walls, flying pixels at its silhouette, 1 mm noise,
 * whole millimetres). Checked against the body's own pixels (its depth image alone):
 *  - the person is kept (>= 97% of the body's pixels) and nothing else (<= 2% of what is kept
 *    is not the body; the floor under the feet, the walls, flying pixels gone), with the planes
 *    and pixels counted in the report;
 *  - a second person standing 1.2 m to the side is removed as another object;
 *  - an empty room (no one near the centre), a body twice a person's size (3.4 m) and a flat board
 *    cut to a person's outline are refused with one line saying what was found;
 *  - a clean depth image (the body alone) keeps nearly all of the body. */
#include "fit_view.h"
#include "test.h"

static spx_ctx *ctx;
static spx_body_model model;
enum { W = 320, H = 240 };

typedef struct scene {
  double *V; /* the body */
  int32_t nv;
  spx_camera cam;
  float body[W * H]; /* the body alone: its depth, 0 elsewhere */
  float raw[W * H];  /* the frame */
} scene;

static void make_scene(scene *s, double scale, int room) {
  s->nv = model.nv;
  s->V = malloc((size_t)model.nv * 3 * sizeof(double));
  CHECK_OK(ctx, synth_posed(ctx, &model, 45, 0.25, s->V));
  for (int32_t i = 0; i < model.nv * 3; i++) s->V[i] *= scale;
  double dir[3] = {0.2, 0.1, 1};
  CHECK(view_camera(ctx, s->V, model.nv, dir, 2.4 * scale, W, H, 0.82 * W, &s->cam) == 0);
  CHECK(view_depth(ctx, s->V, model.nv, model.faces, model.nf, &s->cam, s->body) == 0);
  CHECK(view_room_depth(ctx, s->V, model.nv, model.faces, model.nf, &s->cam, room, 0.001, 3, s->raw) == 0);
}

/* kept: pixels left; of them, not the body's; and the body's pixels left. */
static void tally(const scene *s, const float *d, int64_t *kept, int64_t *stray, double *body_kept) {
  int64_t nb = 0, nbk = 0;
  *kept = *stray = 0;
  for (int p = 0; p < W * H; p++) {
    int isb = s->body[p] > 0 && fabsf(s->raw[p] - s->body[p]) < 0.01f;
    nb += isb;
    if (!(d[p] > 0)) continue;
    (*kept)++;
    if (isb) nbk++;
    else *stray += 1;
  }
  *body_kept = nb ? (double)nbk / nb : 0;
}

static void test_room(void) {
  scene *s = calloc(1, sizeof *s);
  make_scene(s, 1.0, 1);
  float *d = malloc(sizeof s->raw);
  memcpy(d, s->raw, sizeof s->raw);
  spx_fit_depth_report rep;
  CHECK_OK(ctx, spx_fit_depth_person(ctx, "room.png", &s->cam, d, W, H, &rep));
  int64_t kept, stray;
  double frac;
  tally(s, d, &kept, &stray, &frac);
  fprintf(stderr, "  room: %lld px, %d planes (%lld), %lld flying, range %lld, other %lld; kept %lld (%.1f%% of the "
          "body, %lld not the body)\n", (long long)rep.valid, rep.nplanes, (long long)rep.planes, (long long)rep.flying,
          (long long)rep.range, (long long)rep.other, (long long)kept, frac * 100, (long long)stray);
  CHECK(rep.kept == kept && rep.nplanes >= 2 && rep.planes > W * H / 4);
  CHECK_MSG(frac >= 0.97 && stray <= kept / 50, "%.3f of the body kept, %lld stray", frac, (long long)stray);
  CHECK(rep.extent[1] > 1.3 && rep.extent[1] < 2.0); /* a standing person's height */
  /* the body alone (no room): nearly all kept, nothing removed as a plane */
  memcpy(d, s->body, sizeof s->body);
  CHECK_OK(ctx, spx_fit_depth_person(ctx, "clean.png", &s->cam, d, W, H, &rep));
  tally(s, d, &kept, &stray, &frac);
  CHECK_MSG(frac >= 0.98 && rep.nplanes == 0, "%.3f kept, %d planes", frac, rep.nplanes);
  free(d), free(s->V), free(s);
}

static void test_second_person(void) {
  scene *s = calloc(1, sizeof *s);
  make_scene(s, 1.0, 1);
  /* another body 1.2 m to the camera's right, at the same depth */
  double *V2 = malloc((size_t)model.nv * 3 * sizeof(double));
  for (int32_t i = 0; i < model.nv; i++)
    for (int d = 0; d < 3; d++) V2[i * 3 + d] = s->V[i * 3 + d] + 1.2 * s->cam.R[0][d];
  float *other = malloc(sizeof s->raw);
  CHECK(view_depth(ctx, V2, model.nv, model.faces, model.nf, &s->cam, other) == 0);
  int64_t nother = 0;
  for (int p = 0; p < W * H; p++)
    if (other[p] > 0 && (!(s->raw[p] > 0) || other[p] < s->raw[p])) s->raw[p] = other[p], nother++;
  CHECK(nother > 1000);
  spx_fit_depth_report rep;
  CHECK_OK(ctx, spx_fit_depth_person(ctx, "two.png", &s->cam, s->raw, W, H, &rep));
  int64_t kept, stray;
  double frac;
  tally(s, s->raw, &kept, &stray, &frac);
  CHECK_MSG(frac >= 0.97 && stray <= kept / 50 && rep.other > nother / 2, "%.3f kept, %lld stray, %lld other", frac,
            (long long)stray, (long long)rep.other);
  free(V2), free(other), free(s->V), free(s);
}

static void test_refused(void) {
  scene *s = calloc(1, sizeof *s);
  make_scene(s, 1.0, 1);
  /* the same room without anyone: only floor and walls */
  double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30}, eye[3];
  for (int32_t i = 0; i < model.nv; i++)
    for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], s->V[i * 3 + k]), hi[k] = fmax(hi[k], s->V[i * 3 + k]);
  view_eye(&s->cam, eye);
  float *d = malloc(sizeof s->raw);
  for (int p = 0; p < W * H; p++)
    d[p] = (float)view_room_ray(&s->cam, eye, lo[1], 0.5 * (lo[0] + hi[0]), 0.5 * (lo[2] + hi[2]), p % W, p / W);
  spx_fit_depth_report rep;
  CHECK(spx_fit_depth_person(ctx, "empty.png", &s->cam, d, W, H, &rep) == SPX_E_ARG);
  const char *m = spx_ctx_message(ctx);
  CHECK_MSG(strstr(m, "empty.png: no person near the centre") && strstr(m, "planes") && !strchr(m, '\n'), "%s", m);
  free(s->V);
  /* a "person" 3.4 m tall */
  make_scene(s, 2.0, 0);
  CHECK(spx_fit_depth_person(ctx, "giant.png", &s->cam, s->raw, W, H, &rep) == SPX_E_ARG);
  m = spx_ctx_message(ctx);
  CHECK_MSG(strstr(m, "giant.png: the object near the centre is") && strstr(m, "larger than one person"), "%s", m);
  free(s->V);
  /* a cut-out board of a person's outline: the body's pixels on a slanted plane, 1 mm noise */
  make_scene(s, 1.0, 0);
  const double nb[3] = {0.3, 0.1, 1.0};
  for (int p = 0; p < W * H; p++) {
    double rx = (p % W + 0.5 - s->cam.K[0][2]) / s->cam.K[0][0], ry = (p / W + 0.5 - s->cam.K[1][2]) / s->cam.K[1][1];
    d[p] = s->body[p] > 0 ? (float)(2.4 / (nb[0] * rx + nb[1] * ry + nb[2]) + 0.001 * (p * 7919 % 3 - 1)) : 0;
  }
  CHECK(spx_fit_depth_person(ctx, "board.png", &s->cam, d, W, H, &rep) == SPX_E_ARG);
  m = spx_ctx_message(ctx);
  CHECK_MSG(strstr(m, "board.png: the object near the centre is") && strstr(m, "flat"), "%s", m);
  free(d), free(s->V), free(s);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_room), SPX_TEST(test_second_person), SPX_TEST(test_refused)};
  return spx_t_main_body(&ctx, &model, tests, (int)(sizeof tests / sizeof tests[0]));
}
