/* Registration scored against the complete surface of the true body (the mean distance from 30,000
 * noise-free samples of the whole body to the registered surface), from full scans, single views,
 * depth images and several depth images fused.
 *
 * --set outside (default): bodies outside the shipped model's shape space (register_scenes.h: the
 * SMPL-topology woman as she is and made larger with bulges, two `smplpix synth` subjects in loose
 * clothes with hair and shoes, the shipped body at twice the shape range, the shipped body with
 * bulges and widened), each with --seeds seeds (a seed draws the scan's samples and noise and
 * jitters the cameras: azimuth +-20 degrees, 0-0.3 m above the centre, 2.2-2.6 m away). Cases:
 *   full    50,000 samples of the whole surface, 2 mm noise
 *   front   ~100,000 samples kept where a 640x480 camera in front sees them, 2 mm noise, with the
 *           camera's position (side / back: the same from the side / behind)
 *   depth   one 640x480 depth frame from the front (K of a real sensor, f = 525 px): the body in a
 *           room (floor, walls), flying pixels at its silhouette, 1 mm noise, whole millimetres;
 *           the person found by spx_fit_depth_person, back-projected by spx_fit_depth_points
 *   depth4  four such frames from cameras around (azimuths 45, 135, 225, 315 degrees), fused
 * --set inside: the rows of the earlier benchmark (bodies of the model's own space: 0 at rest, then
 * random pose and shape), cases full, holes (five 12 cm holes), front, side, back, above, depth
 * (a clean 640x480 depth image without room or noise), woman (human_woman.obj full, body 0 only).
 * --full: the whole outside table (6 bodies x 3 seeds); the default is 3 bodies x 1 seed.
 * --verbose: each stage's progress, and of every run the complete-surface error split into the part
 * a camera saw and the rest (a full scan: all seen), each with its mean signed distance (+: the
 * registration lies inside the true surface there) and per body region (head, torso, arms, legs:
 * the nearest registered face's most weighted joint), of the registration and of the posed model
 * before the free stage.
 * usage: bench_register_views [--set outside|inside] [--full] [--bodies LIST] [--seeds N] [--threads N]
 *          [--cases LIST] [--no-view] [--scene room|none] [--verbose]... [--pose-steps N] [--inner N]
 *          [--free-steps N] [--points-pose N] [--points-free N] [--w-pose W] [--w-shape W] [--aids BITS]
 * --aids: spx_fit_options.aids (SPX_FIT_AID_* bits; default: the library's), to measure each aid. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "../tests/fit_view.h"
#include "bench_common.h"
#include "body/rot3.h"
#include "core/internal.h" /* spx_now */
#include "register_scenes.h"
#include "smplpix/smplpix.h"

enum { C_FULL, C_HOLES, C_FRONT, C_SIDE, C_BACK, C_ABOVE, C_DEPTH, C_DEPTH4, C_WOMAN, NCASE };
static const char *case_names[NCASE] = {"full", "holes", "front", "side", "back", "above", "depth", "depth4", "woman"};
static const double case_az[NCASE] = {0, 0, 0, 90, 180, 0, 0, 45, 0}; /* degrees */
#define MAXB 8
#define MAXS 8
#define NDEPTH4 4

typedef struct cfg {
  int outside, threads, use_view, room, verbose, pose_steps, inner, free_steps, points_pose, points_free;
  double w_pose, w_shape;
  int aids; /* -1: the library's default */
} cfg;

static void progress(void *user, const spx_fit_progress *p) {
  if (!*(int *)user) return;
  if (p->note) printf("    note: %s\n", p->note);
  else if (p->step == p->nsteps || *(int *)user > 1)
    printf("    %-5s energy %.4e  mean %.2f mm  (%.1f s)\n", p->stage, p->energy, p->mean_dist * 1e3, p->seconds);
}

/* The directions of the inside set's cameras (from the body, 2.4 m from its box's centre). */
static const double inside_dirs[NCASE][3] = {{0, 0, 1}, {0, 0, 1}, {0, 0, 1},    {1, 0, 0}, {0, 0, -1},
                                             {0, 1.2, 1}, {0, 0.15, 1}, {1, 0, 1}, {0, 0, 1}};

/* A camera of case c for seed s: outside, the case's azimuth (+ 90 k for depth4's camera k),
 * jittered; inside, the earlier benchmark's camera. */
static int case_camera(spx_ctx *ctx, const rs_body *b, int c, int k, int s, const cfg *g, spx_camera *cam) {
  if (!g->outside) return view_camera(ctx, b->V, b->nv, inside_dirs[c], 2.4, 640, 480, 525, cam);
  uint64_t r = 0x51ed5eedULL + 7919ULL * (uint64_t)s + 104729ULL * (uint64_t)k + 31ULL * (uint64_t)c;
  double az = case_az[c] + 90.0 * k + 40.0 * (synth_uni(&r) - 0.5), up = 0.3 * synth_uni(&r);
  double dist = 2.2 + 0.4 * synth_uni(&r);
  return rs_camera(ctx, b, az * M_PI / 180.0, up, dist, 640, 480, cam);
}

/* Whether the comma-separated list has this case. */
static int has_case(const char *list, const char *name) {
  size_t n = strlen(name);
  for (const char *p = list; p && *p; p = strchr(p, ',') ? strchr(p, ',') + 1 : NULL)
    if (!strncmp(p, name, n) && (p[n] == ',' || !p[n])) return 1;
  return 0;
}

/* The depth frame of camera cam as the library sees it: the person's points (spx_fit_depth_person,
 * with the room) appended to *scan with camera index k in *views. */
static int depth_points(spx_ctx *ctx, const rs_body *b, const spx_camera *cam, int k, uint64_t seed, const cfg *g,
                        spx_mesh *scan, int32_t **views) {
  size_t npx = (size_t)cam->width * cam->height;
  float *d = malloc(npx * sizeof(float));
  spx_mesh pts = {0};
  spx_fit_depth_report rep;
  int rc = -1;
  /* inside: the earlier rows' clean depth channel in whole millimetres */
  int made = d && (g->outside ? !rs_depth_frame(ctx, b, cam, g->room, seed, d)
                              : !view_depth(ctx, b->V, b->nv, b->F, b->nf, cam, d));
  for (size_t p = 0; made && !g->outside && p < npx; p++) d[p] = roundf(d[p] * 1000.0f) / 1000.0f;
  if (made) {
    if ((!g->room || !spx_fit_depth_person(ctx, "bench depth", cam, d, cam->width, cam->height, &rep)) &&
        !spx_fit_depth_points(ctx, "bench depth", cam, d, cam->width, cam->height, NULL, &pts))
      rc = 0;
    if (!rc && g->room && g->verbose)
      printf("    depth frame %d: %lld px, %lld flying, %d planes %lld, range %lld, other %lld, kept %lld\n", k,
             (long long)rep.valid, (long long)rep.flying, rep.nplanes, (long long)rep.planes, (long long)rep.range,
             (long long)rep.other, (long long)rep.kept);
  }
  free(d);
  if (rc) return -1;
  float *pos = realloc(scan->pos, (size_t)(scan->nv + pts.nv) * 3 * sizeof(float));
  int32_t *v = realloc(*views, (size_t)(scan->nv + pts.nv) * sizeof(int32_t));
  if (pos) scan->pos = pos;
  if (v) *views = v;
  if (!pos || !v) rc = -1;
  for (int32_t i = 0; !rc && i < pts.nv; i++) {
    memcpy(scan->pos + (size_t)(scan->nv + i) * 3, pts.pos + (size_t)i * 3, 3 * sizeof(float));
    (*views)[scan->nv + i] = k;
  }
  if (!rc) scan->nv += pts.nv;
  spx_mesh_free(&pts);
  return rc;
}

/* The scan of case c of body b, seed s; eyes (up to NDEPTH4 x 3) and *neyes: its cameras; *views:
 * each point's camera (depth4). */
static int make_scan(spx_ctx *ctx, int c, const rs_body *b, int s, const cfg *g, spx_mesh *scan, double *eyes,
                     spx_camera *cams, int *neyes, int32_t **views) {
  uint64_t seed = 7 + 1000ULL * (uint64_t)s + (uint64_t)(b->nv % 997);
  memset(scan, 0, sizeof *scan);
  *neyes = 0;
  if (c == C_FULL || c == C_HOLES || c == C_WOMAN) {
    synth_opts so = {50000, c == C_WOMAN ? 0.0 : 0.002, 0.0, 0, 1.0, 0};
    if (synth_scan(b->V, b->nv, b->F, b->nf, &so, seed, scan, NULL, NULL)) return -1;
    if (c == C_HOLES) view_holes(scan, 5, 0.06, seed);
    return 0;
  }
  int ncam = c == C_DEPTH4 ? NDEPTH4 : 1;
  for (int k = 0; k < ncam; k++) {
    spx_camera *cam = cams + k;
    if (case_camera(ctx, b, c, k, s, g, cam)) return -1;
    view_eye(cam, eyes + 3 * k);
    if (c == C_DEPTH || c == C_DEPTH4) {
      if (depth_points(ctx, b, cam, k, seed + 13 * (uint64_t)k, g, scan, views)) return -1;
    } else if (view_scan(ctx, b->V, b->nv, b->F, b->nf, cam, 100000, 0.002, seed, scan)) {
      return -1;
    }
  }
  *neyes = ncam;
  return 0;
}

enum { R_HEAD, R_TORSO, R_ARMS, R_LEGS, NREGION };
static const char *region_names[NREGION] = {"head", "torso", "arms", "legs"};

/* Of one surface against the true one, over the true samples some camera saw (k = 0) and the rest
 * (k = 1): the mean distance, the mean signed distance along the registered surface's normal (+:
 * the true surface lies outside the registration, which is too thin there), and per body region. */
typedef struct split {
  double err[2], sgn[2], reg_err[NREGION][2];
  int32_t n[2], reg_n[NREGION][2];
} split;

typedef struct run_out {
  double err, secs, cpu;
  split fin, posed; /* the registration; the posed model before the free stage (verbose runs) */
  int32_t points;
} run_out;

/* Whether name n holds one of the parts (case-insensitive). */
static int name_has(const char *n, const char *const *parts) {
  for (; *parts; parts++)
    for (const char *c = n; *c; c++)
      if (!strncasecmp(c, *parts, strlen(*parts))) return 1;
  return 0;
}

/* The region of model vertex j: its most weighted joint's name (head and neck, arms and hands,
 * legs and feet, else torso; names of the default body's rig and SMPL). */
static int vertex_region(const spx_body_model *m, int32_t j) {
  static const char *const head[] = {"head", "neck", NULL}, *const arms[] = {"arm", "hand", "thumb", "finger",
                                                                           "elbow", "wrist", NULL},
                           *const legs[] = {"leg", "foot", "toe", "knee", "ankle", NULL};
  int32_t best = 0;
  for (int32_t k = 1; k < m->nj; k++)
    if (m->weights[(size_t)j * m->nj + k] > m->weights[(size_t)j * m->nj + best]) best = k;
  const char *nm = m->joint_names ? m->joint_names[best] : "";
  return name_has(nm, head) ? R_HEAD : name_has(nm, arms) ? R_ARMS : name_has(nm, legs) ? R_LEGS : R_TORSO;
}

/* The split of surface (verts, the model's faces) against the true samples (seen: per sample). */
static void split_surface(spx_ctx *ctx, const spx_body_model *m, const spx_mesh *truth, const unsigned char *seen,
                          const float *verts, split *out) {
  int32_t n = truth->nv, *face = malloc((size_t)n * sizeof(int32_t));
  float *bary = malloc((size_t)n * 3 * sizeof(float)), *dist = malloc((size_t)n * sizeof(float));
  memset(out, 0, sizeof *out);
  if (face && bary && dist &&
      !spx_fit_closest_points(ctx, truth->pos, n, verts, m->nv, m->faces, m->nf, 2, face, bary, dist))
    for (int32_t i = 0; i < n; i++) {
      const int32_t *f = m->faces + (size_t)face[i] * 3;
      const float *a = verts + f[0] * 3, *b = verts + f[1] * 3, *c = verts + f[2] * 3, *x = truth->pos + i * 3;
      double e1[3], e2[3], nn[3], q[3], len = 0, sg = 0;
      for (int d = 0; d < 3; d++) {
        e1[d] = b[d] - a[d], e2[d] = c[d] - a[d];
        q[d] = bary[i * 3] * a[d] + bary[i * 3 + 1] * b[d] + bary[i * 3 + 2] * c[d];
      }
      for (int d = 0; d < 3; d++) nn[d] = e1[(d + 1) % 3] * e2[(d + 2) % 3] - e1[(d + 2) % 3] * e2[(d + 1) % 3];
      for (int d = 0; d < 3; d++) len += nn[d] * nn[d];
      for (int d = 0; d < 3; d++) sg += (x[d] - q[d]) * nn[d];
      int k = seen[i] ? 0 : 1, rg = vertex_region(m, f[0]);
      out->err[k] += dist[i], out->sgn[k] += len > 0 ? sg / sqrt(len) : 0, out->n[k]++;
      out->reg_err[rg][k] += dist[i], out->reg_n[rg][k]++;
    }
  for (int k = 0; k < 2; k++) {
    double c = out->n[k] ? out->n[k] : 1;
    out->err[k] /= c, out->sgn[k] /= c;
    for (int r = 0; r < NREGION; r++) out->reg_err[r][k] /= out->reg_n[r][k] ? out->reg_n[r][k] : 1;
  }
  free(face), free(bary), free(dist);
}

/* The complete-surface error split into the part some camera saw (facing one and not behind its
 * depth image by over 1 cm) and the rest, of the registration and of its posed model (verbose
 * runs). */
static void split_error(spx_ctx *ctx, const spx_body_model *m, const rs_body *b, const spx_fit_result *r,
                        const spx_camera *cams, int ncam, run_out *ro) {
  spx_mesh truth;
  synth_opts so = {30000, 0.0, 0.0, 0, 1.0, 0};
  float *depth = NULL, *posed = NULL;
  if (r->nv != m->nv || synth_scan(b->V, b->nv, b->F, b->nf, &so, 99, &truth, NULL, NULL)) return;
  unsigned char *seen = calloc((size_t)truth.nv, 1);
  for (int32_t i = 0; seen && !ncam && i < truth.nv; i++) seen[i] = 1; /* a full scan: all of it */
  depth = malloc(ncam ? (size_t)cams[0].width * cams[0].height * sizeof(float) : 1);
  posed = malloc((size_t)r->nv * 3 * sizeof(float));
  for (int k = 0; seen && depth && k < ncam; k++) {
    const spx_camera *c = cams + k;
    if (view_depth(ctx, b->V, b->nv, b->F, b->nf, c, depth)) break;
    for (int32_t i = 0; i < truth.nv; i++) {
      const float *x = truth.pos + i * 3;
      double p[3];
      for (int a = 0; a < 3; a++) p[a] = c->R[a][0] * x[0] + c->R[a][1] * x[1] + c->R[a][2] * x[2] + c->t[a];
      if (!(p[2] > 0)) continue;
      double u = (c->K[0][0] * p[0] + c->K[0][1] * p[1]) / p[2] + c->K[0][2], v = c->K[1][1] * p[1] / p[2] + c->K[1][2];
      if (u < 0 || v < 0 || u >= c->width || v >= c->height) continue;
      float dz = depth[(size_t)v * c->width + (size_t)u];
      if (dz > 0 && p[2] < dz + 0.01) seen[i] = 1;
    }
  }
  for (int32_t i = 0; posed && i < r->nv; i++) {
    double x[3];
    spx_rot3_apply(r->sim_R, r->verts_pose + i * 3, x);
    for (int d = 0; d < 3; d++) posed[i * 3 + d] = (float)((r->sim_scale * x[d] + r->sim_t[d]) / r->unit_scale);
  }
  if (seen && depth) split_surface(ctx, m, &truth, seen, r->verts_scan, &ro->fin);
  if (seen && depth && posed) split_surface(ctx, m, &truth, seen, posed, &ro->posed);
  free(seen), free(depth), free(posed);
  spx_mesh_free(&truth);
}

/* The verbose lines of a split. */
static void print_split(const char *what, const split *s) {
  int32_t n = s->n[0] + s->n[1];
  if (!n) return;
  printf("    %-6s seen %.2f mm (signed %+.2f), hidden %.2f mm (signed %+.2f; %.0f%% of the surface)\n", what,
         s->err[0] * 1e3, s->sgn[0] * 1e3, s->err[1] * 1e3, s->sgn[1] * 1e3, 100.0 * s->n[1] / n);
  printf("           by region, seen / hidden mm (hidden share of all):");
  for (int r = 0; r < NREGION; r++)
    printf(" %s %.2f / %.2f (%.0f%%)", region_names[r], s->reg_err[r][0] * 1e3, s->reg_err[r][1] * 1e3,
           100.0 * s->reg_n[r][1] / n);
  printf("\n");
}

/* SPX_BENCH_DUMP=DIR (debugging): the true body, the registration and the cameras of every run as
 * DIR/<body>_<case>_<seed>_{truth,reg}.obj and _cams.json. */
static void dump(spx_ctx *ctx, const rs_body *b, const char *cname, int s, const spx_fit_result *r,
                 const spx_camera *cams, int ncam) {
  const char *dir = getenv("SPX_BENCH_DUMP");
  if (!dir) return;
  char path[1024];
  spx_mesh t = {0}, reg;
  t.nv = b->nv, t.nf = b->nf, t.faces = b->F;
  t.pos = malloc((size_t)b->nv * 3 * sizeof(float));
  for (int32_t i = 0; t.pos && i < b->nv * 3; i++) t.pos[i] = (float)b->V[i];
  snprintf(path, sizeof path, "%s/%s_%s_%d_truth.obj", dir, b->name, cname, s);
  if (t.pos) spx_mesh_save(ctx, path, &t, SPX_MESH_OBJ);
  free(t.pos);
  snprintf(path, sizeof path, "%s/%s_%s_%d_reg.obj", dir, b->name, cname, s);
  if (!spx_fit_result_mesh(ctx, r, &reg)) spx_mesh_save(ctx, path, &reg, SPX_MESH_OBJ), spx_mesh_free(&reg);
  snprintf(path, sizeof path, "%s/%s_%s_%d_reg.json", dir, b->name, cname, s);
  spx_fit_save_json(ctx, path, r, NULL);
  snprintf(path, sizeof path, "%s/%s_%s_%d_cams.json", dir, b->name, cname, s);
  if (ncam) spx_camera_save(ctx, path, cams, ncam);
}

/* One registration of case c; 0, or -1 when the scan could not be made, 1 when the fit failed. */
static int run_case(spx_ctx *ctx, const spx_body_model *m, const rs_body *b, int c, int s, const cfg *g,
                    run_out *ro) {
  spx_mesh scan;
  double eyes[NDEPTH4 * 3];
  spx_camera cams[NDEPTH4];
  int neyes = 0;
  int32_t *views = NULL;
  if (make_scan(ctx, c, b, s, g, &scan, eyes, cams, &neyes, &views)) {
    spx_mesh_free(&scan);
    free(views);
    return -1;
  }
  spx_fit_options o;
  spx_fit_options_default(&o);
  o.threads = g->threads;
  if (g->pose_steps) o.pose_steps = g->pose_steps;
  if (g->inner) o.inner_iterations = g->inner;
  if (g->free_steps) o.free_steps = g->free_steps;
  if (g->points_pose) o.max_points_pose = g->points_pose;
  if (g->points_free) o.max_points_free = g->points_free;
  if (g->w_pose > 0) o.w_pose = g->w_pose;
  if (g->w_shape > 0) o.w_shape = g->w_shape;
  if (g->aids >= 0) o.aids = (unsigned)g->aids;
  o.progress = progress;
  o.progress_user = (void *)&g->verbose;
  if (neyes && g->use_view) o.nviews = neyes, o.view_eyes = eyes, o.point_view = views;
  spx_fit_result r;
  double t0 = spx_now(), c0 = bench_cpu_now();
  int rc = spx_fit_register(ctx, m, &scan, &o, &r) ? 1 : 0;
  ro->secs = spx_now() - t0, ro->cpu = bench_cpu_now() - c0, ro->points = scan.nv;
  if (!rc) ro->err = view_complete_error(ctx, b->V, b->nv, b->F, b->nf, r.verts_scan, r.nv, r.faces, r.nf);
  if (!rc && g->verbose) split_error(ctx, m, b, &r, cams, neyes, ro);
  if (!rc) dump(ctx, b, case_names[c], s, &r, cams, neyes);
  if (!rc) spx_fit_result_free(&r);
  spx_mesh_free(&scan);
  free(views);
  return rc;
}

/* "0,2,5" or "0-5" into list (at most MAXB); returns the count. */
static int parse_list(const char *s, int *list) {
  int n = 0;
  while (*s && n < MAXB) {
    char *end;
    long a = strtol(s, &end, 10), z = a;
    if (end == s) break;
    if (*end == '-') z = strtol(end + 1, &end, 10);
    for (long v = a; v <= z && n < MAXB; v++) list[n++] = (int)v;
    s = *end == ',' ? end + 1 : end;
  }
  return n;
}

static int usage(void) {
  fprintf(stderr, "usage: bench_register_views [--set outside|inside] [--full] [--bodies LIST] [--seeds N] [--threads N]\n"
                  "         [--cases LIST] [--no-view] [--scene room|none] [--verbose]... [--pose-steps N] [--inner N]\n"
                  "         [--free-steps N] [--points-pose N] [--points-free N] [--w-pose W] [--w-shape W] [--aids BITS]\n");
  return 2;
}

/* Per case: mean and worst over the runs, and the goals of the outside set. */
static void summary(const double err[NCASE][MAXB][MAXS], const int ok[NCASE][MAXB][MAXS], const double cpu[NCASE],
                    const int *bodies, int nb, int seeds, const rs_body *names) {
  double mean[NCASE] = {0}, worst[NCASE] = {0};
  int cnt[NCASE] = {0}, fails[NCASE] = {0};
  printf("\ncase     mean mm  worst mm (body, seed)    runs  failed  CPU s/run\n");
  for (int c = 0; c < NCASE; c++) {
    int wb = 0, ws = 0;
    for (int i = 0; i < nb; i++)
      for (int s = 0; s < seeds; s++) {
        if (ok[c][i][s] == 2) fails[c]++;
        if (ok[c][i][s] != 1) continue;
        mean[c] += err[c][i][s], cnt[c]++;
        if (err[c][i][s] > worst[c]) worst[c] = err[c][i][s], wb = i, ws = s;
      }
    if (!cnt[c] && !fails[c]) continue;
    if (cnt[c]) mean[c] /= cnt[c];
    printf("%-7s %7.2f  %7.2f (%s, %d)%*s %4d  %6d  %8.1f\n", case_names[c], mean[c] * 1e3, worst[c] * 1e3,
           names[wb].name, ws, (int)(14 - strlen(names[wb].name)), "", cnt[c], fails[c],
           cpu[c] / (cnt[c] + fails[c]));
  }
  (void)bodies;
  if (!cnt[C_FULL]) return;
  double f = mean[C_FULL] * 1e3, fw = worst[C_FULL] * 1e3;
  printf("goals: full mean %.2f mm (<= 2: %s)", f, f <= 2 ? "met" : "not met");
  int single[2] = {C_FRONT, C_DEPTH};
  for (int k = 0; k < 2; k++)
    if (cnt[single[k]])
      printf("; %s mean %.2f <= %.2f: %s, worst %.2f <= %.2f (2 x worst full + 1): %s", case_names[single[k]],
             mean[single[k]] * 1e3, 2 * f + 1, mean[single[k]] * 1e3 <= 2 * f + 1 ? "met" : "not met",
             worst[single[k]] * 1e3, 2 * fw + 1, worst[single[k]] * 1e3 <= 2 * fw + 1 ? "met" : "not met");
  if (cnt[C_DEPTH4])
    printf("; depth4 mean %.2f <= %.2f (1.2 x full): %s", mean[C_DEPTH4] * 1e3, 1.2 * f,
           mean[C_DEPTH4] * 1e3 <= 1.2 * f ? "met" : "not met");
  printf("\n");
}

int main(int argc, char **argv) {
  cfg g = {.outside = 1, .threads = 2, .use_view = 1, .room = -1, .aids = -1};
  int full = 0, seeds = 0, bodies[MAXB], nb = 0;
  const char *cases = NULL;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--full")) full = 1;
    else if (!strcmp(a, "--no-view")) g.use_view = 0;
    else if (!strcmp(a, "--verbose")) g.verbose++;
    else if (!v) return usage();
    else if (!strcmp(a, "--set") && (!strcmp(v, "outside") || !strcmp(v, "inside"))) g.outside = !strcmp(v, "outside"), i++;
    else if (!strcmp(a, "--scene") && (!strcmp(v, "room") || !strcmp(v, "none"))) g.room = !strcmp(v, "room"), i++;
    else if (!strcmp(a, "--bodies")) nb = parse_list(v, bodies), i++;
    else if (!strcmp(a, "--seeds")) seeds = atoi(v), i++;
    else if (!strcmp(a, "--threads")) g.threads = atoi(v), i++;
    else if (!strcmp(a, "--cases")) cases = v, i++;
    else if (!strcmp(a, "--pose-steps")) g.pose_steps = atoi(v), i++;
    else if (!strcmp(a, "--inner")) g.inner = atoi(v), i++;
    else if (!strcmp(a, "--free-steps")) g.free_steps = atoi(v), i++;
    else if (!strcmp(a, "--points-pose")) g.points_pose = atoi(v), i++;
    else if (!strcmp(a, "--points-free")) g.points_free = atoi(v), i++;
    else if (!strcmp(a, "--w-pose")) g.w_pose = atof(v), i++;
    else if (!strcmp(a, "--w-shape")) g.w_shape = atof(v), i++;
    else if (!strcmp(a, "--aids")) g.aids = (int)strtol(v, NULL, 0), i++;
    else return usage();
  }
  if (g.room < 0) g.room = g.outside;
  if (!nb) nb = g.outside ? (full ? parse_list("0-5", bodies) : parse_list("0,2,5", bodies)) : parse_list("0-2", bodies);
  if (!seeds) seeds = g.outside && full ? 3 : 1;
  if (!cases) cases = g.outside ? "full,front,depth,depth4" : "full,holes,front,side,back,above,depth,woman";
  if (seeds < 1 || seeds > MAXS || g.threads < 1) return usage();
  spx_ctx *ctx = NULL;
  spx_body_model m;
  spx_mesh woman;
  spx_image parts;
  if (spx_ctx_create(&ctx) || spx_body_load(ctx, SPX_REPO_DATA "/body/default_body.npz", &m) ||
      spx_mesh_load(ctx, SPX_REPO_DATA "/body/human_woman.obj", &woman) ||
      spx_png_read(ctx, SPX_REPO_DATA "/body/body_parts_segmentation.png", &parts))
    BENCH_DIE("bench_register_views", ctx, "loading the data");
  static double err[NCASE][MAXB][MAXS];
  static int ok[NCASE][MAXB][MAXS];
  double cpu[NCASE] = {0};
  rs_body names[MAXB];
  printf("complete-surface error (mm), %s set, %d threads, cameras %s, depth frames %s\n",
         g.outside ? "outside" : "inside", g.threads, g.use_view ? "given" : "not given",
         g.room ? "in a room" : "of the body alone");
  for (int i = 0; i < nb; i++) {
    rs_body b;
    if (g.outside ? rs_body_outside(ctx, &m, &woman, &parts, bodies[i], &b) : rs_body_inside(ctx, &m, bodies[i], &b))
      BENCH_DIE("bench_register_views", ctx, "body %d", bodies[i]);
    names[i] = b;
    printf("body %d: %s (%d vertices)\n", bodies[i], b.name, b.nv);
    for (int s = 0; s < seeds; s++)
      for (int c = 0; c < NCASE; c++) {
        if (!has_case(cases, case_names[c])) continue;
        if (c == C_WOMAN && (g.outside || bodies[i] > 0)) continue;
        rs_body wb = b;
        if (c == C_WOMAN) {
          wb.nv = woman.nv, wb.nf = woman.nf, wb.F = woman.faces;
          wb.V = malloc((size_t)woman.nv * 3 * sizeof(double));
          for (int32_t k = 0; wb.V && k < woman.nv * 3; k++) wb.V[k] = woman.pos[k];
        }
        run_out ro;
        memset(&ro, 0, sizeof ro);
        int rc = run_case(ctx, &m, &wb, c, s, &g, &ro);
        if (c == C_WOMAN) free(wb.V);
        if (rc < 0) BENCH_DIE("bench_register_views", ctx, "scan %s of body %d", case_names[c], bodies[i]);
        ok[c][i][s] = rc ? 2 : 1, err[c][i][s] = ro.err, cpu[c] += ro.cpu;
        if (rc) printf("  seed %d %-6s registration failed: %s\n", s, case_names[c], spx_ctx_message(ctx));
        else
          printf("  seed %d %-6s %6.2f mm  %6d points  %5.1f s (CPU %5.1f s)\n", s, case_names[c], ro.err * 1e3,
                 ro.points, ro.secs, ro.cpu);
        if (!rc) print_split("final", &ro.fin), print_split("posed", &ro.posed);
        fflush(stdout);
      }
    free(b.V), free(b.F);
    names[i].V = NULL, names[i].F = NULL;
  }
  summary((const double(*)[MAXB][MAXS])err, (const int(*)[MAXB][MAXS])ok, cpu, bodies, nb, seeds, names);
  spx_image_free(&parts);
  spx_mesh_free(&woman);
  spx_body_free(&m);
  spx_ctx_destroy(ctx);
  return 0;
}
