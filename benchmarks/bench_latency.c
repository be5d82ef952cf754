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

#define DIE(...) BENCH_DIE("bench_latency", ctx, __VA_ARGS__)

static int usage(void) {
  fprintf(stderr, "usage: bench_latency [--frames N] [--slow-frames N] [--warmup N] [--widths 64,32,16] "
                  "[--mesh M.obj] [--camera C.json]\n");
  return 2;
}

int main(int argc, char **argv) {
  int frames = 21, slow_frames = 5, warmup = 2, widths[MAXW] = {64, 32, 16}, nw = 3;
  const char *mesh_path = SPX_REPO_DATA "/body/human_woman.obj", *cam_path = SPX_REPO_DATA "/cameras/default.json";
  char command[1024] = "";
  for (int i = 0; i < argc; i++) {
    size_t l = strlen(command);
    snprintf(command + l, sizeof command - l, "%s%s", i ? " " : "", argv[i]);
  }
  for (int i = 1; i < argc; i++) {
    if (i + 1 >= argc) return usage();
    const char *o = argv[i], *v = argv[++i];
    if (!strcmp(o, "--frames")) frames = atoi(v);
    else if (!strcmp(o, "--slow-frames")) slow_frames = atoi(v);
    else if (!strcmp(o, "--warmup")) warmup = atoi(v);
    else if (!strcmp(o, "--mesh")) mesh_path = v;
    else if (!strcmp(o, "--camera")) cam_path = v;
    else if (!strcmp(o, "--widths")) {
      nw = 0;
      for (const char *p = v; *p && nw < MAXW; p = strchr(p, ',') ? strchr(p, ',') + 1 : p + strlen(p)) {
        int w = atoi(p);
        if (w != 8 && w != 16 && w != 32 && w != 64) return usage();
        widths[nw++] = w;
      }
    } else
      return usage();
  }
  if (frames < 1 || slow_frames < 1 || warmup < 1) return usage();

  spx_ctx *ctx;
  if (spx_ctx_create(&ctx)) return 1;
  if (spx_device_open(ctx, NULL)) DIE("device");
  spx_device_info info;
  spx_device_get_info(ctx, &info);
  spx_mesh meshes[LEVELS];
  if (bench_mesh_levels(ctx, mesh_path, LEVELS, meshes)) DIE("%s", mesh_path);
  spx_camera *cams = NULL;
  int ncams = 0;
  if (spx_camera_load(ctx, cam_path, &cams, &ncams)) DIE("camera");
  const spx_camera cam = cams[0];
  free(cams);
  const int W = cam.width, H = cam.height;
  const size_t npx = (size_t)W * H;
  int mesh_has_uv = meshes[0].uv && meshes[0].face_uv;

  enum { TW = 1024, TH = 1024 };
  float *tex = malloc(sizeof(float) * TW * TH * 3);
  if (!tex) DIE("out of memory");
  bench_checker_texture(tex, TW, TH);

  spx_projector *proj = NULL;
  spx_unet *nets[MAXW] = {NULL};
  if (spx_projector_create(ctx, &proj)) DIE("setup");
  for (int k = 0; k < nw; k++)
    if (spx_unet_create(ctx, widths[k], 0, 1 + (uint64_t)k, &nets[k])) DIE("unet width %d", widths[k]);
  spx_device_tensor *dimg = NULL;
  if (spx_device_tensor_create(ctx, 1, 4, H, W, &dimg)) DIE("device tensor");

  char why[512] = "", cpu[320], load0[64], load1[64];
  peer_llvmpipe *gl = getenv("SPX_BENCH_NO_GL") ? NULL : peer_llvmpipe_open(why, sizeof why);
  if (getenv("SPX_BENCH_NO_GL")) snprintf(why, sizeof why, "SPX_BENCH_NO_GL is set");
  bench_cpu_model(cpu, sizeof cpu);
  loadavg(load0, sizeof load0);

  printf("Renderer latency, %dx%d (%s), one frame = upload positions + colours, render, read back to the host\n", W,
         H, cam_path);
  printf("command: %s\n", command);
  printf("CPU: %s; load average at start: %s\n", cpu, load0);
  printf("OpenCL device: %s (%s, driver %s)\n", info.name, info.platform, info.driver);
  if (gl)
    printf("peer: %s, %s, EGL %s\n", peer_llvmpipe_renderer(gl), peer_llvmpipe_version(gl),
           peer_llvmpipe_platform(gl));
  else
    printf("llvmpipe peer skipped: %s\n", why);
  printf("UNet weights are random (PyTorch default init): latency does not depend on their values\n");
  printf("textured rows: %s, 1024x1024 procedural checker texture\n",
         mesh_has_uv ? "the mesh's UVs" : "the mesh has no UVs: spherical UVs generated");
  printf("%d warm-up frames, then %d timed (%d when a warm-up frame takes > %.0f s), the three meshes round-robin "
         "frame by frame (llvmpipe: one after another); wall ms median [min, max]; cpu = process CPU ms per frame "
         "(all threads)\n\n",
         warmup, frames, slow_frames, SLOW_S);

  row rows[NROWS];
  memset(rows, 0, sizeof rows);
  int nr = 0, r_proj = nr++, r_pref = nr++, r_unet0 = nr;
  nr += nw;
  int r_rast = nr;
  nr += 3;
  int r_gl = nr++;
#define NAME(r, n, l) snprintf(rows[r].name, sizeof rows[0].name, "%s", n), snprintf(rows[r].label, sizeof rows[0].label, "%s", l)
  NAME(r_proj, "project", "SMPLpix projection (spx_project)");
  NAME(r_pref, "project C ref", "projection, plain-C reference, 1 thread");
  for (int k = 0; k < nw; k++) {
    snprintf(rows[r_unet0 + k].name, sizeof rows[0].name, "project+unet%d", widths[k]);
    snprintf(rows[r_unet0 + k].label, sizeof rows[0].label, "SMPLpix projection + UNet width %d", widths[k]);
  }
  NAME(r_rast, "raster colours", "our rasterizer, vertex colours");
  NAME(r_rast + 1, "raster textured", "our rasterizer, textured");
  NAME(r_rast + 2, "raster textured+aa2", "our rasterizer, textured + AA 2x");
  NAME(r_gl, "llvmpipe colours", "Mesa llvmpipe, vertex colours");
#undef NAME
  for (int r = 0; r < nr; r++) {
    rows[r].present = r != r_gl || gl;
    for (int l = 0; l < LEVELS; l++) {
      rows[r].s[l].med = rows[r].s[l].min = rows[r].s[l].max = NAN;
      rows[r].cpu[l] = NAN;
      rows[r].drawn[l] = -1;
    }
  }

  printf("%-20s %8s %8s %6s  %-28s %9s %9s\n", "renderer", "verts", "faces", "frames", "median [min, max] ms",
         "cpu ms", "drawn px");
  char checks[LEVELS][256];
  /* per level: colours, UVs, an output image, a rasterizer (its faces/UVs/texture stay resident) */
  float *cols[LEVELS] = {NULL}, *uvs[LEVELS] = {NULL}, *outs[LEVELS] = {NULL}, *refs[LEVELS] = {NULL};
  spx_rasterizer *rasts[LEVELS] = {NULL};
  frame_job jobs[LEVELS];
  void *users[LEVELS];
  memset(jobs, 0, sizeof jobs);
  for (int l = 0; l < LEVELS; l++) {
    const spx_mesh *m = &meshes[l];
    cols[l] = malloc(sizeof(float) * 3 * (size_t)m->nv);
    outs[l] = malloc(sizeof(float) * 4 * npx);
    refs[l] = malloc(sizeof(float) * 4 * npx);
    if (!cols[l] || !outs[l] || !refs[l] || bench_colours_from_normals(m, cols[l])) DIE("out of memory");
    if (!mesh_has_uv) {
      if (!(uvs[l] = malloc(sizeof(float) * 2 * (size_t)m->nv))) DIE("out of memory");
      bench_spherical_uv(m, uvs[l]);
    }
    if (spx_rasterizer_create(ctx, &rasts[l])) DIE("rasterizer");
    frame_job *j = &jobs[l];
    j->ctx = ctx, j->proj = proj, j->rast = rasts[l], j->gl = gl, j->pos = m->pos, j->col = cols[l], j->cam = &cam;
    j->nv = m->nv, j->W = W, j->H = H, j->out = outs[l], j->dimg = dimg;
    spx_project_args pa = {1, m->nv, m->pos, cols[l], 1, &cam, SPX_LAYOUT_HWC};
    j->pa = pa, j->na = pa;
    j->na.layout = SPX_LAYOUT_NCHW;
    users[l] = j;
    snprintf(checks[l], sizeof checks[l], "%d v: no llvmpipe image", m->nv);
  }
  for (int r = 0; r < nr; r++) {
    if (!rows[r].present) continue;
    for (int l = 0; l < LEVELS; l++) {
      const spx_mesh *m = &meshes[l];
      frame_job *j = &jobs[l];
      if (r == r_proj) {
        j->k = K_PROJECT;
      } else if (r == r_pref) {
        j->k = K_PROJECT_REF;
      } else if (r < r_rast) {
        j->k = K_UNET, j->unet = nets[r - r_unet0];
      } else if (r < r_gl) {
        int mode = r - r_rast;
        j->k = K_RASTER;
        memset(&j->ra, 0, sizeof j->ra);
        j->ra.nverts = m->nv, j->ra.pos = m->pos, j->ra.col = cols[l], j->ra.nfaces = m->nf, j->ra.faces = m->faces;
        j->ra.ncams = 1, j->ra.cams = &cam, j->ra.aa = mode == 2 ? 2 : 1, j->ra.layout = SPX_LAYOUT_HWC;
        j->ra.static_id = (uint32_t)(mode + 1);
        if (mode) {
          j->ra.nuv = mesh_has_uv ? m->nuv : m->nv, j->ra.uv = mesh_has_uv ? m->uv : uvs[l];
          j->ra.face_uv = mesh_has_uv ? m->face_uv : m->faces;
          j->ra.tex = tex, j->ra.tex_width = TW, j->ra.tex_height = TH, j->ra.tex_channels = 3;
          j->ra.wrap = SPX_WRAP_REPEAT;
        }
      } else {
        j->k = K_GL;
      }
    }
    int rc = 0;
    if (r == r_gl) { /* one mesh resident in the GL context at a time: the levels one after another */
      for (int l = 0; l < LEVELS && !rc; l++) {
        const spx_mesh *m = &meshes[l];
        if (peer_llvmpipe_upload(gl, m->nv, m->pos, cols[l], m->nf, m->faces, jobs[l].why, sizeof jobs[l].why))
          rc = -1;
        else
          rc = bench_time(frame, &jobs[l], warmup, frames, SLOW_S, slow_frames, &rows[r].s[l], &rows[r].cpu[l]);
        if (rc) fprintf(stderr, "bench_latency: llvmpipe: %s\n", jobs[l].why);
      }
    } else { /* the three levels round-robin, frame by frame */
      rc = bench_time_interleaved(frame, users, LEVELS, warmup, frames, SLOW_S, slow_frames, rows[r].s, rows[r].cpu);
      if (rc) fprintf(stderr, "bench_latency: %s: %s\n", rows[r].name, spx_ctx_message(ctx));
    }
    if (rc) return 1;
    for (int l = 0; l < LEVELS; l++) {
      const spx_mesh *m = &meshes[l];
      if (jobs[l].k != K_UNET) rows[r].drawn[l] = covered(outs[l], npx, 0);
      if (r == r_rast) memcpy(refs[l], outs[l], sizeof(float) * 4 * npx);
      if (r == r_gl) {
        long differ = 0;
        for (size_t i = 0; i < npx; i++) differ += (outs[l][4 * i + 3] != 1.0f) != (refs[l][4 * i + 3] != 1.0f);
        snprintf(checks[l], sizeof checks[l], "%d v: llvmpipe and our rasterizer differ in coverage at %ld px (%.2f%%)",
                 m->nv, differ, 100.0 * differ / (double)npx);
      }
      const bench_stats *st = &rows[r].s[l];
      char t[64], d[24] = "-";
      snprintf(t, sizeof t, "%.2f [%.2f, %.2f]", st->med, st->min, st->max);
      if (rows[r].drawn[l] >= 0) snprintf(d, sizeof d, "%ld", rows[r].drawn[l]);
      printf("%-20s %8d %8d %6d  %-28s %9.2f %9s\n", rows[r].name, m->nv, m->nf, st->n, t, rows[r].cpu[l], d);
    }
    fflush(stdout);
  }
  for (int l = 0; l < LEVELS; l++) {
    spx_rasterizer_destroy(rasts[l]);
    free(cols[l]), free(uvs[l]), free(outs[l]), free(refs[l]);
  }
  loadavg(load1, sizeof load1);
  printf("\nload average at end: %s\n", load1);
  for (int l = 0; l < LEVELS; l++) printf("check: %s\n", checks[l]);

  /* ratios within this run */
  double xs[LEVELS];
  for (int l = 0; l < LEVELS; l++) xs[l] = meshes[l].nv;
  printf("\ngrowth from %d to %d vertices, same run: median wall time ratio (process CPU time ratio)\n", meshes[0].nv,
         meshes[LEVELS - 1].nv);
  for (int r = 0; r < nr; r++)
    if (rows[r].present)
      printf("  %-20s %6.2fx (%5.2fx)\n", rows[r].name, rows[r].s[LEVELS - 1].med / rows[r].s[0].med,
             rows[r].cpu[LEVELS - 1] / rows[r].cpu[0]);
  int g1 = -1;
  double rat[2] = {NAN, NAN};
  if (gl) {
    g1 = 1;
    for (int l = 0; l < 2; l++) {
      rat[l] = rows[r_rast].s[l].med / rows[r_gl].s[l].med;
      if (!(rat[l] <= 1.0)) g1 = 0;
    }
  }
  /* goal 2: the SMPLpix path (projection + network) grows < 2x; the projection alone reported too */
  double growth = rows[r_proj].s[LEVELS - 1].med / rows[r_proj].s[0].med, ugrowth[MAXW];
  int g2 = 1;
  for (int k = 0; k < nw; k++) {
    const row *u = &rows[r_unet0 + k];
    ugrowth[k] = u->s[LEVELS - 1].med / u->s[0].med;
    if (!(ugrowth[k] < 2.0)) g2 = 0;
  }
  if (gl)
    printf("goal 1, our rasterizer (colours) no slower than llvmpipe at %d and %d vertices: %s (ours/llvmpipe "
           "%.2f, %.2f)\n",
           meshes[0].nv, meshes[1].nv, g1 ? "HOLDS" : "FAILS", rat[0], rat[1]);
  else
    printf("goal 1 (rasterizer vs llvmpipe): not measured (%s)\n", why);
  if (nw) {
    printf("goal 2, SMPLpix path (projection + UNet) grows < 2x from %d to %d vertices: %s (", meshes[0].nv,
           meshes[LEVELS - 1].nv, g2 ? "HOLDS" : "FAILS");
    for (int k = 0; k < nw; k++) printf("%swidth %d %.2fx", k ? ", " : "", widths[k], ugrowth[k]);
    printf(")\n");
  }
  printf("        projection alone (spx_project) grows %.2fx: %s 2x", growth, growth < 2.0 ? "below" : "NOT below");
  if (nw)
    printf("; at %d vertices it is %.1f%% of the width-%d SMPLpix frame", meshes[LEVELS - 1].nv,
           100.0 * rows[r_proj].s[LEVELS - 1].med / rows[r_unet0 + nw - 1].s[LEVELS - 1].med, widths[nw - 1]);
  printf("\n");

  /* files */
  if (bench_out_dir()) {
    fprintf(stderr, "bench_latency: cannot create out/bench\n");
    return 1;
  }
  FILE *f = fopen("out/bench/latency.csv", "w");
  if (f) {
    fprintf(f, "renderer,vertices,faces,frames,median_ms,min_ms,max_ms,cpu_ms,drawn_px\n");
    for (int r = 0; r < nr; r++)
      for (int l = 0; l < LEVELS && rows[r].present; l++)
        fprintf(f, "%s,%d,%d,%d,%.4f,%.4f,%.4f,%.4f,%ld\n", rows[r].name, meshes[l].nv, meshes[l].nf,
                rows[r].s[l].n, rows[r].s[l].med, rows[r].s[l].min, rows[r].s[l].max, rows[r].cpu[l],
                rows[r].drawn[l]);
    fclose(f);
  }
  cJSON *js = cJSON_CreateObject();
  cJSON_AddStringToObject(js, "command", command);
  cJSON_AddStringToObject(js, "cpu", cpu);
  cJSON_AddStringToObject(js, "device", info.name);
  cJSON_AddStringToObject(js, "platform", info.platform);
  cJSON_AddStringToObject(js, "driver", info.driver);
  cJSON_AddStringToObject(js, "llvmpipe", gl ? peer_llvmpipe_renderer(gl) : "");
  if (!gl) cJSON_AddStringToObject(js, "llvmpipe_skipped", why);
  cJSON_AddStringToObject(js, "load_start", load0);
  cJSON_AddStringToObject(js, "load_end", load1);
  cJSON_AddNumberToObject(js, "width", W);
  cJSON_AddNumberToObject(js, "height", H);
  cJSON_AddNumberToObject(js, "warmup", warmup);
  cJSON_AddStringToObject(js, "uv", mesh_has_uv ? "mesh" : "spherical (generated)");
  cJSON_AddStringToObject(js, "unet_weights", "random (latency does not depend on them)");
  cJSON *arr = cJSON_AddArrayToObject(js, "rows");
  for (int r = 0; r < nr; r++)
    for (int l = 0; l < LEVELS && rows[r].present; l++) {
      cJSON *o = cJSON_CreateObject();
      cJSON_AddStringToObject(o, "renderer", rows[r].name);
      cJSON_AddNumberToObject(o, "vertices", meshes[l].nv);
      cJSON_AddNumberToObject(o, "faces", meshes[l].nf);
      cJSON_AddNumberToObject(o, "frames", rows[r].s[l].n);
      cJSON_AddNumberToObject(o, "median_ms", rows[r].s[l].med);
      cJSON_AddNumberToObject(o, "min_ms", rows[r].s[l].min);
      cJSON_AddNumberToObject(o, "max_ms", rows[r].s[l].max);
      cJSON_AddNumberToObject(o, "cpu_ms", rows[r].cpu[l]);
      if (rows[r].drawn[l] >= 0) cJSON_AddNumberToObject(o, "drawn_px", (double)rows[r].drawn[l]);
      cJSON_AddItemToArray(arr, o);
    }
  cJSON *goals = cJSON_AddObjectToObject(js, "goals");
  if (g1 >= 0) {
    cJSON_AddBoolToObject(goals, "raster_not_slower_than_llvmpipe", g1);
    cJSON_AddNumberToObject(goals, "raster_over_llvmpipe_6890", rat[0]);
    cJSON_AddNumberToObject(goals, "raster_over_llvmpipe_27554", rat[1]);
  }
  if (nw) cJSON_AddBoolToObject(goals, "smplpix_growth_below_2x", g2);
  for (int k = 0; k < nw; k++) {
    char key[48];
    snprintf(key, sizeof key, "smplpix_growth_width%d", widths[k]);
    cJSON_AddNumberToObject(goals, key, ugrowth[k]);
  }
  cJSON_AddNumberToObject(goals, "projection_alone_growth", growth);
  char *txt = cJSON_Print(js);
  f = fopen("out/bench/latency.json", "w");
  if (f && txt) fprintf(f, "%s\n", txt);
  if (f) fclose(f);
  cJSON_free(txt);
  cJSON_Delete(js);

  char title[128];
  snprintf(title, sizeof title, "Renderer latency vs vertices, %dx%d", W, H);
  plot *pl = plot_create(900, 700, title, "vertices (body mesh, 0 / 1 / 2 Loop subdivisions)",
                         "ms per frame: upload + render + read-back (median)", 1, 1);
  if (pl) {
    /* plot order: the palette has 8 colours, so the 9th series (the C reference, far below the
     * others) repeats the first colour with another marker */
    int order[NROWS], no = 0;
    for (int r = 0; r < nr; r++)
      if (r != r_pref) order[no++] = r;
    order[no++] = r_pref;
    for (int oi = 0; oi < no; oi++) {
      int r = order[oi];
      if (!rows[r].present) continue;
      double ys[LEVELS];
      for (int l = 0; l < LEVELS; l++) ys[l] = rows[r].s[l].med;
      plot_series(pl, rows[r].label, LEVELS, xs, ys);
    }
    if (plot_save(pl, "out/bench/latency.png", why, sizeof why)) fprintf(stderr, "bench_latency: %s\n", why);
    plot_free(pl);
  }
  printf("\nwrote out/bench/latency.csv, out/bench/latency.json, out/bench/latency.png\n");

  peer_llvmpipe_close(gl);
  spx_device_tensor_free(dimg);
  for (int k = 0; k < nw; k++) spx_unet_destroy(nets[k]);
  spx_projector_destroy(proj);
  for (int l = 0; l < LEVELS; l++) spx_mesh_free(&meshes[l]);
  free(tex);
  spx_ctx_destroy(ctx);
  return 0;
}
