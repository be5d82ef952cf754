/* Renderer latency vs geometry: the paper's claim that a mesh rasterizer's latency grows with the
 * number of vertices while SMPLpix's is almost independent of it and is spent in the network.
 *
 * One process, one run, at the size of data/cameras/default.json (410x308), for the body mesh
 * (data/body/human_woman.obj, SMPL topology, 6,890 vertices) and its Loop subdivisions (27,554 and
 * 110,210 vertices), per-vertex colours from the normals. Every frame uploads the positions and
 * colours (a posed body changes every frame), renders and reads the image back to the host:
 *  (a) project       spx_project: projection + collision (z-buffer), RGB-D image read back;
 *      project C ref spx_project_ref, the single-threaded plain-C reference of the same (for
 *                    scale: what the projection costs without the OpenCL runtime);
 *  (b) project+unetW projection straight into the UNet on the device through the public device
 *                    tensor (spx_project_to_tensor -> spx_unet_forward_tensor, no host round trip
 *                    between them; the path `smplpix render --mesh` runs), eval mode (batch
 *                    norm folded, fused ReLU), widths 64, 32, 16, RGB output read back. The
 *                    weights are random (PyTorch's default init): latency does not depend on them;
 *  (c) raster        spx_raster: per-vertex colours; textured (procedural checker texture, the
 *                    mesh's UVs or, when it has none, spherical UVs); textured + 2x2 AA. Faces,
 *                    UVs and the texture stay resident (static_id), like GL buffer objects;
 *  (d) llvmpipe      Mesa llvmpipe (peer_llvmpipe.c, EGL surfaceless) drawing the same mesh with
 *                    per-vertex colours: glBufferSubData of positions + colours, draw, glReadPixels.
 * Per row: warm-up frames, then median / min / max wall ms over N frames (fewer, --slow-frames,
 * for rows whose warm-up frame takes over 1 s: the width-64 UNet on a CPU), and process CPU ms.
 * The three meshes are timed round-robin, frame by frame, so a row's growth ratios see the same
 * machine load (the machine this was written on is shared); llvmpipe holds one mesh at a time,
 * so its three sizes run one after another.
 * Output: a table on stdout, out/bench/latency.csv, out/bench/latency.json, out/bench/latency.png.
 *
 *   bench_latency [--frames N (21)] [--slow-frames N (5)] [--warmup N (2)] [--widths 64,32,16]
 *                 [--mesh M.obj] [--camera C.json]          SPX_BENCH_NO_GL=1 skips llvmpipe */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "bench_common.h"
#include "core/internal.h"
#include "peer_llvmpipe.h"
#include "plot.h"
#include "smplpix/smplpix.h"

#define LEVELS 3
#define MAXW 4
#define NROWS (2 + MAXW + 3 + 1)
#define SLOW_S 1.0

typedef enum { K_PROJECT, K_PROJECT_REF, K_UNET, K_RASTER, K_GL } kind;

typedef struct frame_job {
  kind k;
  spx_ctx *ctx;
  /* (a), (b) */
  spx_projector *proj;
  spx_project_args pa;
  spx_project_args na; /* the same as pa, NCHW for the network */
  spx_device_tensor *dimg;
  spx_unet *unet;
  /* (c) */
  spx_rasterizer *rast;
  spx_raster_args ra;
  /* (d) */
  peer_llvmpipe *gl;
  const float *pos, *col;
  const spx_camera *cam;
  int nv, W, H;
  float *out;
  char why[512];
} frame_job;

static int frame(void *user) {
  frame_job *j = user;
  switch (j->k) {
  case K_PROJECT:
    return spx_project(j->ctx, j->proj, &j->pa, j->out, NULL);
  case K_PROJECT_REF:
    return spx_project_ref(j->ctx, &j->pa, j->out, NULL);
  case K_UNET: { /* positions and colours are uploaded inside spx_project_to_tensor */
    spx_status st = spx_project_to_tensor(j->ctx, j->proj, &j->na, j->dimg);
    if (!st) st = spx_unet_forward_tensor(j->unet, j->dimg, j->out);
    return st;
  }
  case K_RASTER:
    return spx_raster(j->ctx, j->rast, &j->ra, j->out, NULL);
  case K_GL:
    if (peer_llvmpipe_update(j->gl, j->pos, j->col, j->why, sizeof j->why)) return -1;
    return peer_llvmpipe_draw(j->gl, j->cam, j->out, j->why, sizeof j->why);
  }
  return -1;
}

typedef struct row {
  char name[48];
  char label[80]; /* in the plot's legend */
  int present; /* 0: skipped */
  bench_stats s[LEVELS];
  double cpu[LEVELS];
  long drawn[LEVELS]; /* covered pixels of the image (-1: not an RGB-D image) */
} row;

static long covered(const float *img, size_t npx, int nchw) {
  long n = 0;
  for (size_t i = 0; i < npx; i++) n += (nchw ? img[3 * npx + i] : img[4 * i + 3]) != 1.0f;
  return n;
}

static void loadavg(char *buf, size_t cap) {
  snprintf(buf, cap, "?");
  FILE *f = fopen("/proc/loadavg", "r");
  if (!f) return;
  double a, b, c;
  if (fscanf(f, "%lf %lf %lf", &a, &b, &c) == 3) snprintf(buf, cap, "%.2f %.2f %.2f", a, b, c);
  fclose(f);
}

enum { TW = 1024, TH = 1024 }; /* the checker texture of the textured rows */

/* One run: the options, the device, meshes and renderers, the rows timed, the goals. */
typedef struct run {
  int frames, slow_frames, warmup, widths[MAXW], nw;
  const char *mesh_path, *cam_path;
  char command[1024];
  spx_ctx *ctx;
  spx_device_info info;
  spx_mesh meshes[LEVELS];
  spx_camera cam;
  int W, H, mesh_has_uv;
  size_t npx;
  float *tex;
  spx_projector *proj;
  spx_unet *nets[MAXW];
  spx_device_tensor *dimg;
  peer_llvmpipe *gl;
  char why[512], cpu[320], load0[64], load1[64];
  row rows[NROWS];
  int nr, r_proj, r_pref, r_unet0, r_rast, r_gl;
  /* per level: colours, UVs, an output image, a rasterizer (its faces/UVs/texture stay resident) */
  float *cols[LEVELS], *uvs[LEVELS], *outs[LEVELS], *refs[LEVELS];
  spx_rasterizer *rasts[LEVELS];
  frame_job jobs[LEVELS];
  void *users[LEVELS];
  char checks[LEVELS][256];
  int g1, g2; /* the goals: -1 not measured, 0 fails, 1 holds */
  double rat[2], growth, ugrowth[MAXW];
} run;

#define DIE(...) BENCH_DIE("bench_latency", b->ctx, __VA_ARGS__)

static int usage(void) {
  fprintf(stderr, "usage: bench_latency [--frames N] [--slow-frames N] [--warmup N] [--widths 64,32,16] "
                  "[--mesh M.obj] [--camera C.json]\n");
  return 2;
}

static int parse_args(run *b, int argc, char **argv) {
  b->frames = 21, b->slow_frames = 5, b->warmup = 2, b->nw = 3;
  b->widths[0] = 64, b->widths[1] = 32, b->widths[2] = 16;
  b->mesh_path = SPX_REPO_DATA "/body/human_woman.obj", b->cam_path = SPX_REPO_DATA "/cameras/default.json";
  for (int i = 0; i < argc; i++) {
    size_t l = strlen(b->command);
    snprintf(b->command + l, sizeof b->command - l, "%s%s", i ? " " : "", argv[i]);
  }
  for (int i = 1; i < argc; i++) {
    if (i + 1 >= argc) return usage();
    const char *o = argv[i], *v = argv[++i];
    if (!strcmp(o, "--frames")) b->frames = atoi(v);
    else if (!strcmp(o, "--slow-frames")) b->slow_frames = atoi(v);
    else if (!strcmp(o, "--warmup")) b->warmup = atoi(v);
    else if (!strcmp(o, "--mesh")) b->mesh_path = v;
    else if (!strcmp(o, "--camera")) b->cam_path = v;
    else if (!strcmp(o, "--widths")) {
      b->nw = 0;
      for (const char *p = v; *p && b->nw < MAXW; p = strchr(p, ',') ? strchr(p, ',') + 1 : p + strlen(p)) {
        int w = atoi(p);
        if (w != 8 && w != 16 && w != 32 && w != 64) return usage();
        b->widths[b->nw++] = w;
      }
    } else
      return usage();
  }
  if (b->frames < 1 || b->slow_frames < 1 || b->warmup < 1) return usage();
  return 0;
}

/* The device, the meshes and camera, the texture, the projector, the networks and llvmpipe. */
static int setup(run *b) {
  if (spx_device_open(b->ctx, NULL)) DIE("device");
  spx_device_get_info(b->ctx, &b->info);
  if (bench_mesh_levels(b->ctx, b->mesh_path, LEVELS, b->meshes)) DIE("%s", b->mesh_path);
  spx_camera *cams = NULL;
  int ncams = 0;
  if (spx_camera_load(b->ctx, b->cam_path, &cams, &ncams)) DIE("camera");
  b->cam = cams[0];
  free(cams);
  b->W = b->cam.width, b->H = b->cam.height;
  b->npx = (size_t)b->W * b->H;
  b->mesh_has_uv = b->meshes[0].uv && b->meshes[0].face_uv;
  b->tex = malloc(sizeof(float) * TW * TH * 3);
  if (!b->tex) DIE("out of memory");
  bench_checker_texture(b->tex, TW, TH);
  if (spx_projector_create(b->ctx, &b->proj)) DIE("setup");
  for (int k = 0; k < b->nw; k++)
    if (spx_unet_create(b->ctx, b->widths[k], 0, 1 + (uint64_t)k, &b->nets[k])) DIE("unet width %d", b->widths[k]);
  if (spx_device_tensor_create(b->ctx, 1, 4, b->H, b->W, &b->dimg)) DIE("device tensor");
  b->gl = getenv("SPX_BENCH_NO_GL") ? NULL : peer_llvmpipe_open(b->why, sizeof b->why);
  if (getenv("SPX_BENCH_NO_GL")) snprintf(b->why, sizeof b->why, "SPX_BENCH_NO_GL is set");
  bench_cpu_model(b->cpu, sizeof b->cpu);
  loadavg(b->load0, sizeof b->load0);
  return 0;
}

static void print_header(const run *b) {
  printf("Renderer latency, %dx%d (%s), one frame = upload positions + colours, render, read back to the host\n", b->W,
         b->H, b->cam_path);
  printf("command: %s\n", b->command);
  printf("CPU: %s; load average at start: %s\n", b->cpu, b->load0);
  printf("OpenCL device: %s (%s, driver %s)\n", b->info.name, b->info.platform, b->info.driver);
  if (b->gl)
    printf("peer: %s, %s, EGL %s\n", peer_llvmpipe_renderer(b->gl), peer_llvmpipe_version(b->gl),
           peer_llvmpipe_platform(b->gl));
  else
    printf("llvmpipe peer skipped: %s\n", b->why);
  printf("UNet weights are random (PyTorch default init): latency does not depend on their values\n");
  printf("textured rows: %s, 1024x1024 procedural checker texture\n",
         b->mesh_has_uv ? "the mesh's UVs" : "the mesh has no UVs: spherical UVs generated");
  printf("%d warm-up frames, then %d timed (%d when a warm-up frame takes > %.0f s), the three meshes round-robin "
         "frame by frame (llvmpipe: one after another); wall ms median [min, max]; cpu = process CPU ms per frame "
         "(all threads)\n\n",
         b->warmup, b->frames, b->slow_frames, SLOW_S);
}

static void name_row(row *r, const char *name, const char *label) {
  snprintf(r->name, sizeof r->name, "%s", name);
  snprintf(r->label, sizeof r->label, "%s", label);
}

/* The rows in their order: projection, its C reference, projection + each UNet, the three
 * rasterizer modes, llvmpipe (present only when it opened). */
static void init_rows(run *b) {
  row *rows = b->rows;
  memset(rows, 0, sizeof b->rows);
  int nr = 0;
  b->r_proj = nr++, b->r_pref = nr++, b->r_unet0 = nr;
  nr += b->nw;
  b->r_rast = nr;
  nr += 3;
  b->r_gl = nr++;
  b->nr = nr;
  name_row(&rows[b->r_proj], "project", "SMPLpix projection (spx_project)");
  name_row(&rows[b->r_pref], "project C ref", "projection, plain-C reference, 1 thread");
  for (int k = 0; k < b->nw; k++) {
    snprintf(rows[b->r_unet0 + k].name, sizeof rows[0].name, "project+unet%d", b->widths[k]);
    snprintf(rows[b->r_unet0 + k].label, sizeof rows[0].label, "SMPLpix projection + UNet width %d", b->widths[k]);
  }
  name_row(&rows[b->r_rast], "raster colours", "our rasterizer, vertex colours");
  name_row(&rows[b->r_rast + 1], "raster textured", "our rasterizer, textured");
  name_row(&rows[b->r_rast + 2], "raster textured+aa2", "our rasterizer, textured + AA 2x");
  name_row(&rows[b->r_gl], "llvmpipe colours", "Mesa llvmpipe, vertex colours");
  for (int r = 0; r < nr; r++) {
    rows[r].present = r != b->r_gl || b->gl;
    for (int l = 0; l < LEVELS; l++) {
      rows[r].s[l].med = rows[r].s[l].min = rows[r].s[l].max = NAN;
      rows[r].cpu[l] = NAN;
      rows[r].drawn[l] = -1;
    }
  }
}

/* Per level: the colours, UVs (spherical when the mesh has none), images, rasterizer and job. */
static int prepare_levels(run *b) {
  for (int l = 0; l < LEVELS; l++) {
    const spx_mesh *m = &b->meshes[l];
    b->cols[l] = malloc(sizeof(float) * 3 * (size_t)m->nv);
    b->outs[l] = malloc(sizeof(float) * 4 * b->npx);
    b->refs[l] = malloc(sizeof(float) * 4 * b->npx);
    if (!b->cols[l] || !b->outs[l] || !b->refs[l] || bench_colours_from_normals(m, b->cols[l])) DIE("out of memory");
    if (!b->mesh_has_uv) {
      if (!(b->uvs[l] = malloc(sizeof(float) * 2 * (size_t)m->nv))) DIE("out of memory");
      bench_spherical_uv(m, b->uvs[l]);
    }
    if (spx_rasterizer_create(b->ctx, &b->rasts[l])) DIE("rasterizer");
    frame_job *j = &b->jobs[l];
    j->ctx = b->ctx, j->proj = b->proj, j->rast = b->rasts[l], j->gl = b->gl, j->pos = m->pos, j->col = b->cols[l];
    j->cam = &b->cam, j->nv = m->nv, j->W = b->W, j->H = b->H, j->out = b->outs[l], j->dimg = b->dimg;
    spx_project_args pa = {1, m->nv, m->pos, b->cols[l], 1, &b->cam, SPX_LAYOUT_HWC};
    j->pa = pa, j->na = pa;
    j->na.layout = SPX_LAYOUT_NCHW;
    b->users[l] = j;
    snprintf(b->checks[l], sizeof b->checks[l], "%d v: no llvmpipe image", m->nv);
  }
  return 0;
}

/* The rasterizer job of mode 0 (colours), 1 (textured) or 2 (textured, 2x2 AA) at level l. */
static void raster_job(run *b, int l, int mode) {
  const spx_mesh *m = &b->meshes[l];
  frame_job *j = &b->jobs[l];
  j->k = K_RASTER;
  memset(&j->ra, 0, sizeof j->ra);
  j->ra.nverts = m->nv, j->ra.pos = m->pos, j->ra.col = b->cols[l], j->ra.nfaces = m->nf, j->ra.faces = m->faces;
  j->ra.ncams = 1, j->ra.cams = &b->cam, j->ra.aa = mode == 2 ? 2 : 1, j->ra.layout = SPX_LAYOUT_HWC;
  j->ra.static_id = (uint32_t)(mode + 1);
  if (mode) {
    j->ra.nuv = b->mesh_has_uv ? m->nuv : m->nv, j->ra.uv = b->mesh_has_uv ? m->uv : b->uvs[l];
    j->ra.face_uv = b->mesh_has_uv ? m->face_uv : m->faces;
    j->ra.tex = b->tex, j->ra.tex_width = TW, j->ra.tex_height = TH, j->ra.tex_channels = 3;
    j->ra.wrap = SPX_WRAP_REPEAT;
  }
}

/* Row r's frames at every level; 0, or -1 after saying why. */
static int time_row(run *b, int r) {
  for (int l = 0; l < LEVELS; l++) {
    frame_job *j = &b->jobs[l];
    if (r == b->r_proj) j->k = K_PROJECT;
    else if (r == b->r_pref) j->k = K_PROJECT_REF;
    else if (r < b->r_rast) j->k = K_UNET, j->unet = b->nets[r - b->r_unet0];
    else if (r < b->r_gl) raster_job(b, l, r - b->r_rast);
    else j->k = K_GL;
  }
  row *rw = &b->rows[r];
  int rc = 0;
  if (r == b->r_gl) { /* one mesh resident in the GL context at a time: the levels one after another */
    for (int l = 0; l < LEVELS && !rc; l++) {
      const spx_mesh *m = &b->meshes[l];
      frame_job *j = &b->jobs[l];
      if (peer_llvmpipe_upload(b->gl, m->nv, m->pos, b->cols[l], m->nf, m->faces, j->why, sizeof j->why))
        rc = -1;
      else
        rc = bench_time(frame, j, b->warmup, b->frames, SLOW_S, b->slow_frames, &rw->s[l], &rw->cpu[l]);
      if (rc) fprintf(stderr, "bench_latency: llvmpipe: %s\n", j->why);
    }
  } else { /* the three levels round-robin, frame by frame */
    rc = bench_time_interleaved(frame, b->users, LEVELS, b->warmup, b->frames, SLOW_S, b->slow_frames, rw->s, rw->cpu);
    if (rc) fprintf(stderr, "bench_latency: %s: %s\n", rw->name, spx_ctx_message(b->ctx));
  }
  return rc;
}

/* Row r's table lines; the llvmpipe row's coverage compared with the rasterizer's (colours). */
static void print_row(run *b, int r) {
  row *rw = &b->rows[r];
  for (int l = 0; l < LEVELS; l++) {
    const spx_mesh *m = &b->meshes[l];
    const float *out = b->outs[l], *ref = b->refs[l];
    if (b->jobs[l].k != K_UNET) rw->drawn[l] = covered(out, b->npx, 0);
    if (r == b->r_rast) memcpy(b->refs[l], out, sizeof(float) * 4 * b->npx);
    if (r == b->r_gl) {
      long differ = 0;
      for (size_t i = 0; i < b->npx; i++) differ += (out[4 * i + 3] != 1.0f) != (ref[4 * i + 3] != 1.0f);
      snprintf(b->checks[l], sizeof b->checks[l],
               "%d v: llvmpipe and our rasterizer differ in coverage at %ld px (%.2f%%)", m->nv, differ,
               100.0 * differ / (double)b->npx);
    }
    const bench_stats *st = &rw->s[l];
    char t[64], d[24] = "-";
    snprintf(t, sizeof t, "%.2f [%.2f, %.2f]", st->med, st->min, st->max);
    if (rw->drawn[l] >= 0) snprintf(d, sizeof d, "%ld", rw->drawn[l]);
    printf("%-20s %8d %8d %6d  %-28s %9.2f %9s\n", rw->name, m->nv, m->nf, st->n, t, rw->cpu[l], d);
  }
  fflush(stdout);
}

/* The growth ratios within this run and the two goals. */
static void report_goals(run *b) {
  const row *rows = b->rows;
  const spx_mesh *meshes = b->meshes;
  printf("\ngrowth from %d to %d vertices, same run: median wall time ratio (process CPU time ratio)\n", meshes[0].nv,
         meshes[LEVELS - 1].nv);
  for (int r = 0; r < b->nr; r++)
    if (rows[r].present)
      printf("  %-20s %6.2fx (%5.2fx)\n", rows[r].name, rows[r].s[LEVELS - 1].med / rows[r].s[0].med,
             rows[r].cpu[LEVELS - 1] / rows[r].cpu[0]);
  b->g1 = -1;
  b->rat[0] = b->rat[1] = NAN;
  if (b->gl) {
    b->g1 = 1;
    for (int l = 0; l < 2; l++) {
      b->rat[l] = rows[b->r_rast].s[l].med / rows[b->r_gl].s[l].med;
      if (!(b->rat[l] <= 1.0)) b->g1 = 0;
    }
  }
  /* goal 2: the SMPLpix path (projection + network) grows < 2x; the projection alone reported too */
  b->growth = rows[b->r_proj].s[LEVELS - 1].med / rows[b->r_proj].s[0].med;
  b->g2 = 1;
  for (int k = 0; k < b->nw; k++) {
    const row *u = &rows[b->r_unet0 + k];
    b->ugrowth[k] = u->s[LEVELS - 1].med / u->s[0].med;
    if (!(b->ugrowth[k] < 2.0)) b->g2 = 0;
  }
  if (b->gl)
    printf("goal 1, our rasterizer (colours) no slower than llvmpipe at %d and %d vertices: %s (ours/llvmpipe "
           "%.2f, %.2f)\n",
           meshes[0].nv, meshes[1].nv, b->g1 ? "HOLDS" : "FAILS", b->rat[0], b->rat[1]);
  else
    printf("goal 1 (rasterizer vs llvmpipe): not measured (%s)\n", b->why);
  if (b->nw) {
    printf("goal 2, SMPLpix path (projection + UNet) grows < 2x from %d to %d vertices: %s (", meshes[0].nv,
           meshes[LEVELS - 1].nv, b->g2 ? "HOLDS" : "FAILS");
    for (int k = 0; k < b->nw; k++) printf("%swidth %d %.2fx", k ? ", " : "", b->widths[k], b->ugrowth[k]);
    printf(")\n");
  }
  printf("        projection alone (spx_project) grows %.2fx: %s 2x", b->growth,
         b->growth < 2.0 ? "below" : "NOT below");
  if (b->nw)
    printf("; at %d vertices it is %.1f%% of the width-%d SMPLpix frame", meshes[LEVELS - 1].nv,
           100.0 * rows[b->r_proj].s[LEVELS - 1].med / rows[b->r_unet0 + b->nw - 1].s[LEVELS - 1].med,
           b->widths[b->nw - 1]);
  printf("\n");
}

static void write_csv(const run *b) {
  FILE *f = fopen("out/bench/latency.csv", "w");
  if (!f) return;
  fprintf(f, "renderer,vertices,faces,frames,median_ms,min_ms,max_ms,cpu_ms,drawn_px\n");
  for (int r = 0; r < b->nr; r++)
    for (int l = 0; l < LEVELS && b->rows[r].present; l++) {
      const row *rw = &b->rows[r];
      fprintf(f, "%s,%d,%d,%d,%.4f,%.4f,%.4f,%.4f,%ld\n", rw->name, b->meshes[l].nv, b->meshes[l].nf, rw->s[l].n,
              rw->s[l].med, rw->s[l].min, rw->s[l].max, rw->cpu[l], rw->drawn[l]);
    }
  fclose(f);
}

static cJSON *json_row(const run *b, int r, int l) {
  const row *rw = &b->rows[r];
  cJSON *o = cJSON_CreateObject();
  cJSON_AddStringToObject(o, "renderer", rw->name);
  cJSON_AddNumberToObject(o, "vertices", b->meshes[l].nv);
  cJSON_AddNumberToObject(o, "faces", b->meshes[l].nf);
  cJSON_AddNumberToObject(o, "frames", rw->s[l].n);
  cJSON_AddNumberToObject(o, "median_ms", rw->s[l].med);
  cJSON_AddNumberToObject(o, "min_ms", rw->s[l].min);
  cJSON_AddNumberToObject(o, "max_ms", rw->s[l].max);
  cJSON_AddNumberToObject(o, "cpu_ms", rw->cpu[l]);
  if (rw->drawn[l] >= 0) cJSON_AddNumberToObject(o, "drawn_px", (double)rw->drawn[l]);
  return o;
}

static void write_json(const run *b) {
  cJSON *js = cJSON_CreateObject();
  cJSON_AddStringToObject(js, "command", b->command);
  cJSON_AddStringToObject(js, "cpu", b->cpu);
  cJSON_AddStringToObject(js, "device", b->info.name);
  cJSON_AddStringToObject(js, "platform", b->info.platform);
  cJSON_AddStringToObject(js, "driver", b->info.driver);
  cJSON_AddStringToObject(js, "llvmpipe", b->gl ? peer_llvmpipe_renderer(b->gl) : "");
  if (!b->gl) cJSON_AddStringToObject(js, "llvmpipe_skipped", b->why);
  cJSON_AddStringToObject(js, "load_start", b->load0);
  cJSON_AddStringToObject(js, "load_end", b->load1);
  cJSON_AddNumberToObject(js, "width", b->W);
  cJSON_AddNumberToObject(js, "height", b->H);
  cJSON_AddNumberToObject(js, "warmup", b->warmup);
  cJSON_AddStringToObject(js, "uv", b->mesh_has_uv ? "mesh" : "spherical (generated)");
  cJSON_AddStringToObject(js, "unet_weights", "random (latency does not depend on them)");
  cJSON *arr = cJSON_AddArrayToObject(js, "rows");
  for (int r = 0; r < b->nr; r++)
    for (int l = 0; l < LEVELS && b->rows[r].present; l++) cJSON_AddItemToArray(arr, json_row(b, r, l));
  cJSON *goals = cJSON_AddObjectToObject(js, "goals");
  if (b->g1 >= 0) {
    cJSON_AddBoolToObject(goals, "raster_not_slower_than_llvmpipe", b->g1);
    cJSON_AddNumberToObject(goals, "raster_over_llvmpipe_6890", b->rat[0]);
    cJSON_AddNumberToObject(goals, "raster_over_llvmpipe_27554", b->rat[1]);
  }
  if (b->nw) cJSON_AddBoolToObject(goals, "smplpix_growth_below_2x", b->g2);
  for (int k = 0; k < b->nw; k++) {
    char key[48];
    snprintf(key, sizeof key, "smplpix_growth_width%d", b->widths[k]);
    cJSON_AddNumberToObject(goals, key, b->ugrowth[k]);
  }
  cJSON_AddNumberToObject(goals, "projection_alone_growth", b->growth);
  char *txt = cJSON_Print(js);
  FILE *f = fopen("out/bench/latency.json", "w");
  if (f && txt) fprintf(f, "%s\n", txt);
  if (f) fclose(f);
  cJSON_free(txt);
  cJSON_Delete(js);
}

static void write_plot(run *b) {
  char title[128];
  snprintf(title, sizeof title, "Renderer latency vs vertices, %dx%d", b->W, b->H);
  plot *pl = plot_create(900, 700, title, "vertices (body mesh, 0 / 1 / 2 Loop subdivisions)",
                         "ms per frame: upload + render + read-back (median)", 1, 1);
  if (!pl) return;
  double xs[LEVELS];
  for (int l = 0; l < LEVELS; l++) xs[l] = b->meshes[l].nv;
  /* plot order: the palette has 8 colours, so the 9th series (the C reference, far below the
   * others) repeats the first colour with another marker */
  int order[NROWS], no = 0;
  for (int r = 0; r < b->nr; r++)
    if (r != b->r_pref) order[no++] = r;
  order[no++] = b->r_pref;
  for (int oi = 0; oi < no; oi++) {
    const row *rw = &b->rows[order[oi]];
    if (!rw->present) continue;
    double ys[LEVELS];
    for (int l = 0; l < LEVELS; l++) ys[l] = rw->s[l].med;
    plot_series(pl, rw->label, LEVELS, xs, ys);
  }
  if (plot_save(pl, "out/bench/latency.png", b->why, sizeof b->why)) fprintf(stderr, "bench_latency: %s\n", b->why);
  plot_free(pl);
}

static void release(run *b) {
  for (int l = 0; l < LEVELS; l++) {
    spx_rasterizer_destroy(b->rasts[l]);
    free(b->cols[l]), free(b->uvs[l]), free(b->outs[l]), free(b->refs[l]);
    b->rasts[l] = NULL, b->cols[l] = b->uvs[l] = b->outs[l] = b->refs[l] = NULL;
  }
}

int main(int argc, char **argv) {
  static run b0;
  run *b = &b0;
  int rc = parse_args(b, argc, argv);
  if (rc) return rc;
  if (spx_ctx_create(&b->ctx)) return 1;
  if ((rc = setup(b))) return rc;
  print_header(b);
  init_rows(b);
  printf("%-20s %8s %8s %6s  %-28s %9s %9s\n", "renderer", "verts", "faces", "frames", "median [min, max] ms",
         "cpu ms", "drawn px");
  if ((rc = prepare_levels(b))) return rc;
  for (int r = 0; r < b->nr; r++) {
    if (!b->rows[r].present) continue;
    if (time_row(b, r)) return 1;
    print_row(b, r);
  }
  release(b);
  loadavg(b->load1, sizeof b->load1);
  printf("\nload average at end: %s\n", b->load1);
  for (int l = 0; l < LEVELS; l++) printf("check: %s\n", b->checks[l]);
  report_goals(b);
  if (bench_out_dir()) {
    fprintf(stderr, "bench_latency: cannot create out/bench\n");
    return 1;
  }
  write_csv(b);
  write_json(b);
  write_plot(b);
  printf("\nwrote out/bench/latency.csv, out/bench/latency.json, out/bench/latency.png\n");
  peer_llvmpipe_close(b->gl);
  spx_device_tensor_free(b->dimg);
  for (int k = 0; k < b->nw; k++) spx_unet_destroy(b->nets[k]);
  spx_projector_destroy(b->proj);
  for (int l = 0; l < LEVELS; l++) spx_mesh_free(&b->meshes[l]);
  free(b->tex);
  spx_ctx_destroy(b->ctx);
  return 0;
}
