/* Registration on synthetic scans of the default body: random pose / shape / translation, surface
 * samples with 2 mm noise, 20% of the points removed in patches, a random rigid transform (any of
 * the six axis-aligned ups). The recovered vertices must land within 5 mm (mean over the seeds,
 * each seed under 8 mm). A scan in millimetres must be detected and converted. The full 20-seed
 * protocol on 50k-point scans is benchmarks/bench_register.c. */
#include "fit_synth.h"
#include "test.h"

static spx_ctx *ctx;
static spx_body_model model;

typedef struct notes {
  char last[160];
  int rigid, pose, free_;
} notes;

static void on_progress(void *user, const spx_fit_progress *p) {
  notes *n = user;
  if (p->note) snprintf(n->last, sizeof n->last, "%s", p->note);
  else if (!strcmp(p->stage, "rigid")) n->rigid++;
  else if (!strcmp(p->stage, "pose")) n->pose++;
  else if (!strcmp(p->stage, "free")) n->free_++;
  if (!p->note) CHECK(isfinite(p->energy) && p->energy >= 0 && isfinite(p->mean_dist));
}

/* spx_fit_register of scan with o, the progress it reports counted in *nt. */
static spx_status register_noted(const spx_mesh *scan, spx_fit_options *o, notes *nt, spx_fit_result *r) {
  memset(nt, 0, sizeof *nt);
  o->progress = on_progress;
  o->progress_user = nt;
  return spx_fit_register(ctx, &model, scan, o, r);
}

/* mean distance between the registration (scan space) and the true vertices (scan space) */
static double vertex_error(const spx_fit_result *r, const double *V, const double R[9], const double t[3], double units,
                           int use_pose_stage) {
  double e = 0;
  for (int32_t i = 0; i < r->nv; i++) {
    double x[3], y[3], d2 = 0;
    for (int d = 0; d < 3; d++)
      x[d] = units * (R[d * 3] * V[i * 3] + R[d * 3 + 1] * V[i * 3 + 1] + R[d * 3 + 2] * V[i * 3 + 2] + t[d]);
    for (int d = 0; d < 3; d++) {
      if (use_pose_stage) {
        const double *p = r->verts_pose + i * 3;
        y[d] = (r->sim_scale * (r->sim_R[d * 3] * p[0] + r->sim_R[d * 3 + 1] * p[1] + r->sim_R[d * 3 + 2] * p[2]) +
                r->sim_t[d]) / r->unit_scale;
      } else {
        y[d] = r->verts_scan[i * 3 + d];
      }
      d2 += (y[d] - x[d]) * (y[d] - x[d]);
    }
    e += sqrt(d2);
  }
  return e / r->nv / units;
}

static void test_synthetic_seeds(void) {
  static const uint64_t seeds[] = {3, 4};
  const int n = (int)(sizeof seeds / sizeof seeds[0]);
  double sum = 0;
  double *V = malloc((size_t)model.nv * 3 * sizeof(double));
  double *pose = calloc((size_t)model.nj * 3, sizeof(double)), *betas = calloc((size_t)model.nbetas, sizeof(double));
  for (int k = 0; k < n; k++) {
    double trans[3], R[9], t[3];
    synth_body(&model, seeds[k], 0.3, pose, betas, trans);
    spx_body_params p = {model.nbetas, betas, pose, trans, NULL};
    CHECK_OK(ctx, spx_body_forward_ref(ctx, &model, &p, V, NULL));
    synth_opts so = {20000, 0.002, 0.2, 1, 1.0, 0};
    spx_mesh scan;
    CHECK(synth_scan(V, model.nv, model.faces, model.nf, &so, seeds[k], &scan, R, t) == 0);
    CHECK(scan.nv > 15000 && scan.nv <= 16100); /* 20% removed */
    spx_fit_options o;
    spx_fit_options_default(&o);
    o.threads = 2;
    o.max_points_free = 12000;
    o.free_steps = 3;
    notes nt;
    spx_fit_result r;
    CHECK_OK(ctx, register_noted(&scan, &o, &nt, &r));
    CHECK(nt.rigid == 1 && nt.pose == o.pose_steps && nt.free_ == o.free_steps);
    CHECK(nt.last[0] == 0); /* metres: no unit note */
    CHECK(r.unit_scale == 1.0);
    CHECK(r.stages_done == SPX_FIT_ALL);
    double ep = vertex_error(&r, V, R, t, 1.0, 1), ef = vertex_error(&r, V, R, t, 1.0, 0);
    fprintf(stderr, "  seed %llu: mean vertex error pose+shape %.2f mm, final %.2f mm; scan mean %.2f mm (%.1f s)\n",
            (unsigned long long)seeds[k], ep * 1e3, ef * 1e3, r.stage_mean[2] * 1e3,
            r.stage_seconds[0] + r.stage_seconds[1] + r.stage_seconds[2]);
    CHECK_MSG(ef < 0.008, "seed %llu: %.2f mm", (unsigned long long)seeds[k], ef * 1e3);
    CHECK(r.stage_mean[2] < 0.0025); /* noise is 2 mm: scan → surface mean about 1.6 mm */
    CHECK(r.stage_mean[2] <= r.stage_mean[1] + 1e-4);
    sum += ef;
    spx_fit_result_free(&r);
    spx_mesh_free(&scan);
  }
  CHECK_MSG(sum / n < 0.005, "mean over seeds %.2f mm", sum / n * 1e3);
  free(V), free(pose), free(betas);
}

static void test_millimetres(void) {
  double *V = malloc((size_t)model.nv * 3 * sizeof(double)), R[9], t[3];
  CHECK_OK(ctx, synth_posed(ctx, &model, 11, 0.2, V));
  synth_opts so = {8000, 0.002, 0.0, 1, 1000.0, 0};
  spx_mesh scan;
  CHECK(synth_scan(V, model.nv, model.faces, model.nf, &so, 11, &scan, R, t) == 0);
  spx_fit_options o;
  spx_fit_options_default(&o);
  o.stages = SPX_FIT_RIGID | SPX_FIT_POSE;
  o.pose_steps = 12;
  notes nt;
  spx_fit_result r;
  CHECK_OK(ctx, register_noted(&scan, &o, &nt, &r));
  CHECK_MSG(!strcmp(nt.last, "scan looks like millimetres, scaling by 0.001"), "note: '%s'", nt.last);
  CHECK(r.unit_scale == 0.001);
  CHECK(nt.free_ == 0 && r.stages_done == (SPX_FIT_RIGID | SPX_FIT_POSE));
  /* outputs are in the scan's units (mm); the error is measured in metres */
  double e = vertex_error(&r, V, R, t, 1000.0, 0);
  fprintf(stderr, "  mm scan: mean vertex error %.2f mm\n", e * 1e3);
  CHECK(e < 0.01);
  CHECK(fabs(r.sim_scale * r.body_scale - 1.0) < 0.05);
  spx_fit_result_free(&r);
  /* the same scan with the units given: no note, same scale */
  o.unit_scale = 0.001;
  CHECK_OK(ctx, register_noted(&scan, &o, &nt, &r));
  CHECK(nt.last[0] == 0 && r.unit_scale == 0.001);
  spx_fit_result_free(&r);
  spx_mesh_free(&scan);
  free(V);
}

int main(void) {
  static const spx_t_test tests[] = {SPX_TEST(test_millimetres), SPX_TEST(test_synthetic_seeds)};
  return spx_t_main_body(&ctx, &model, tests, (int)(sizeof tests / sizeof tests[0]));
}
