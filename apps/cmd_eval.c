/* smplpix eval: PSNR, SSIM, LPIPS (the cached weights of `make weights`, or --lpips W) and detail
 * (the mean absolute image gradient, prediction / target) of predicted images against targets,
 * for two files or two folders matched by name (smplpix/metrics.h does the arithmetic). */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli_scene.h"

static const char *ABOUT =
    "P and T are two image files, or two folders whose files are matched by name (the extension may\n"
    "differ: .png, .exr, .npy as HxWxC or HxW). Only the first three channels (RGB in [0,1]) are\n"
    "compared: the alpha of an RGBA PNG, the depth of an RGB-D EXR are ignored.\n"
    "PSNR = 10 log10(1/MSE) per image (inf for identical images); SSIM as scikit-image's\n"
    "structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False,\n"
    "data_range=1.0, channel_axis=-1) (images of at least 11x11); both are averaged over the images.\n"
    "LPIPS (v0.1, AlexNet, as the lpips package computes it) runs on the OpenCL device, for images\n"
    "of at least 31x31, with the weights `make weights` puts in ${SPX_CACHE_DIR:-~/.cache/smplpix}/\n"
    "weights/lpips_alex.safetensors when that file exists (smaller images: n/a).\n"
    "Detail: the mean absolute image gradient of the prediction over that of the target (1 = as\n"
    "much edge and print detail, below 1 = blurred), inside the mask, or without --mask inside the\n"
    "target's non-background (not white) pixels; also over the full image (smplpix/metrics.h).\n"
    "A size mismatch, an unreadable file or a name present on one side only: one line, exit 1,\n"
    "no JSON written.\n";

typedef struct item {
  char *name, *pred, *target, *mask;
  spx_metrics m;
  spx_detail d;
  double lpips[2]; /* whole image, inside the mask (NAN without one) */
} item;

typedef struct list {
  item *it;
  int n, cap;
} list;

static void list_free(list *l) {
  for (int i = 0; i < l->n; i++) free(l->it[i].name), free(l->it[i].pred), free(l->it[i].target), free(l->it[i].mask);
  free(l->it);
  memset(l, 0, sizeof *l);
}

static int is_dir(const char *p) {
  struct stat sb;
  return stat(p, &sb) == 0 && S_ISDIR(sb.st_mode);
}

static char *join(const char *dir, const char *name) {
  size_t n = strlen(dir) + strlen(name) + 2;
  char *p = malloc(n);
  if (p) snprintf(p, n, "%s/%s", dir, name);
  return p;
}

static size_t stem_len(const char *name) {
  const char *dot = strrchr(name, '.');
  return dot ? (size_t)(dot - name) : strlen(name);
}

static int cmp_name(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* The image files of folder `dir` (sorted by name). Two files with one stem are an error. */
static int list_dir(const char *dir, char ***names, int *count) {
  *names = NULL;
  *count = 0;
  DIR *d = opendir(dir);
  if (!d) return spx_cli_errorf("eval", "%s: cannot open folder (%s)", dir, strerror(errno));
  int cap = 0, rc = SPX_EXIT_OK;
  struct dirent *e;
  while ((e = readdir(d))) {
    if (e->d_name[0] == '.' || !spx_image_ext_ok(e->d_name)) continue;
    if (*count == cap) {
      cap = cap ? 2 * cap : 64;
      char **nn = realloc(*names, sizeof(char *) * (size_t)cap);
      if (!nn) {
        rc = spx_cli_errorf("eval", "out of memory listing %s", dir);
        break;
      }
      *names = nn;
    }
    if (!((*names)[*count] = strdup(e->d_name))) {
      rc = spx_cli_errorf("eval", "out of memory listing %s", dir);
      break;
    }
    (*count)++;
  }
  closedir(d);
  if (!rc && *count)
    qsort(*names, (size_t)*count, sizeof(char *), cmp_name);
  for (int i = 0; !rc && *count > 1 && i < *count; i++) {
    for (int j = i + 1; j < *count; j++) {
      size_t a = stem_len((*names)[i]), b = stem_len((*names)[j]);
      if (a == b && !strncmp((*names)[i], (*names)[j], a)) {
        rc = spx_cli_errorf("eval", "%s: both %s and %s have the name %.*s", dir, (*names)[i], (*names)[j], (int)a,
                            (*names)[i]);
        break;
      }
      if (strncmp((*names)[i], (*names)[j], a)) break; /* sorted: no later name shares the stem prefix */
    }
  }
  return rc;
}

static void names_free(char **n, int count) {
  for (int i = 0; i < count; i++) free(n[i]);
  free(n);
}

/* The entry of names[] with the stem `stem` (length len), or NULL. */
static const char *find_stem(char **names, int count, const char *stem, size_t len) {
  for (int i = 0; i < count; i++)
    if (stem_len(names[i]) == len && !strncmp(names[i], stem, len)) return names[i];
  return NULL;
}

static int add_item(list *l, const char *name, size_t len, char *pred, char *target, char *mask) {
  if (l->n == l->cap) {
    int cap = l->cap ? 2 * l->cap : 16;
    item *ni = realloc(l->it, sizeof(item) * (size_t)cap);
    if (!ni) goto oom;
    l->it = ni;
    l->cap = cap;
  }
  item *it = &l->it[l->n];
  memset(it, 0, sizeof *it);
  it->name = strndup(name, len);
  if (!it->name) goto oom;
  it->pred = pred, it->target = target, it->mask = mask;
  l->n++;
  return SPX_EXIT_OK;
oom:
  free(pred), free(target), free(mask);
  return spx_cli_errorf("eval", "out of memory");
}

/* Pair P and T (files or folders) and the masks into l. */
static int pair_up(const char *pd, const char *td, const char *md, list *l) {
  int pdir = is_dir(pd), tdir = is_dir(td), mdir = md && is_dir(md);
  if (pdir != tdir)
    return spx_cli_errorf("eval", "%s is a %s but %s is a %s: give two files or two folders", pd,
                          pdir ? "folder" : "file", td, tdir ? "folder" : "file");
  if (!pdir) {
    if (mdir) return spx_cli_errorf("eval", "%s is a folder, but --pred and --target are files", md);
    const char *base = strrchr(pd, '/');
    base = base ? base + 1 : pd;
    char *a = strdup(pd), *b = strdup(td), *c = md ? strdup(md) : NULL;
    if (!a || !b || (md && !c)) {
      free(a), free(b), free(c);
      return spx_cli_errorf("eval", "out of memory");
    }
    return add_item(l, base, stem_len(base), a, b, c);
  }
  char **pn = NULL, **tn = NULL, **mn = NULL;
  int np = 0, nt = 0, nm = 0, rc;
  if ((rc = list_dir(pd, &pn, &np)) || (rc = list_dir(td, &tn, &nt)) || (mdir && (rc = list_dir(md, &mn, &nm))))
    goto done;
  if (!np) {
    rc = spx_cli_errorf("eval", "%s: no .png, .exr or .npy images", pd);
    goto done;
  }
  for (int i = 0; i < nt; i++)
    if (!find_stem(pn, np, tn[i], stem_len(tn[i]))) {
      rc = spx_cli_errorf("eval", "%s/%s has no prediction in %s", td, tn[i], pd);
      goto done;
    }
  for (int i = 0; i < np && !rc; i++) {
    size_t len = stem_len(pn[i]);
    const char *t = find_stem(tn, nt, pn[i], len), *m = mdir ? find_stem(mn, nm, pn[i], len) : NULL;
    if (!t) {
      rc = spx_cli_errorf("eval", "%s/%s has no target in %s", pd, pn[i], td);
      break;
    }
    if (mdir && !m) {
      rc = spx_cli_errorf("eval", "%s/%s has no mask in %s", pd, pn[i], md);
      break;
    }
    char *a = join(pd, pn[i]), *b = join(td, t), *c = mdir ? join(md, m) : md ? strdup(md) : NULL;
    if (!a || !b || (md && !c)) {
      free(a), free(b), free(c);
      rc = spx_cli_errorf("eval", "out of memory");
      break;
    }
    rc = add_item(l, pn[i], len, a, b, c);
  }
done:
  names_free(pn, np), names_free(tn, nt), names_free(mn, nm);
  return rc;
}

/* Any image file as HWC floats: .png, .exr (R,G,B,Z), .npy (HxW or HxWxC, any numeric dtype). */
static int load_image(spx_ctx *ctx, const char *path, int need_rgb, spx_image *img) {
  memset(img, 0, sizeof *img);
  if (!spx_image_ext_ok(path)) return spx_cli_errorf("eval", "%s: unknown image type (expected .png, .exr or .npy)", path);
  if (spx_image_read(ctx, path, img)) return spx_cli_error("eval", ctx);
  if (need_rgb && img->channels < 3) {
    int c = img->channels;
    spx_image_free(img);
    return spx_cli_errorf("eval", "%s: %d channel%s, expected an RGB image", path, c, c == 1 ? "" : "s");
  }
  return SPX_EXIT_OK;
}

/* One image pair: load, check sizes, compute. lp_opt: LPIPS was not asked for by --lpips (the
 * cached weights), so an image too small for AlexNet gets n/a instead of an error. */
static int measure(spx_ctx *ctx, spx_lpips *lp, int lp_opt, item *it) {
  spx_image p = {0}, t = {0}, m = {0};
  int rc;
  if ((rc = load_image(ctx, it->pred, 1, &p)) || (rc = load_image(ctx, it->target, 1, &t)) ||
      (it->mask && (rc = load_image(ctx, it->mask, 0, &m))))
    goto done;
  if (p.width != t.width || p.height != t.height) {
    rc = spx_cli_errorf("eval", "%s is %dx%d but %s is %dx%d", it->pred, p.width, p.height, it->target, t.width,
                        t.height);
    goto done;
  }
  if (it->mask && (m.width != p.width || m.height != p.height)) {
    rc = spx_cli_errorf("eval", "%s is %dx%d but %s is %dx%d", it->mask, m.width, m.height, it->pred, p.width,
                        p.height);
    goto done;
  }
  if (spx_image_metrics(ctx, &p, &t, it->mask ? &m : NULL, &it->m)) {
    rc = spx_cli_errorf("eval", "%s: %s", it->pred, spx_ctx_message(ctx));
    goto done;
  }
  if (it->mask && it->m.fg_pixels == 0) {
    rc = spx_cli_errorf("eval", "%s: the mask has no foreground pixels", it->mask);
    goto done;
  }
  if (spx_image_detail(ctx, &p, &t, it->mask ? &m : NULL, &it->d)) {
    rc = spx_cli_errorf("eval", "%s: %s", it->pred, spx_ctx_message(ctx));
    goto done;
  }
  it->lpips[0] = it->lpips[1] = NAN;
  if (lp && lp_opt && (p.width < SPX_LPIPS_MIN_SIZE || p.height < SPX_LPIPS_MIN_SIZE)) goto done; /* n/a */
  if (lp && spx_lpips_distance_masked(lp, &p, &t, it->mask ? &m : NULL, &it->lpips[0], &it->lpips[1]))
    rc = spx_cli_errorf("eval", "%s: %s", it->pred, spx_ctx_message(ctx));
done:
  spx_image_free(&p), spx_image_free(&t), spx_image_free(&m);
  return rc;
}

/* A value for the text line: "inf", "n/a" (undefined) or the number. */
static const char *num(char *buf, size_t cap, const char *fmt, double v) {
  if (isnan(v)) snprintf(buf, cap, "n/a");
  else if (isinf(v)) snprintf(buf, cap, "%sinf", v < 0 ? "-" : "");
  else snprintf(buf, cap, fmt, v);
  return buf;
}

static void print_line(const char *lead, const spx_metrics *m, const spx_detail *d, const double *lpips, int has_lpips,
                       int has_mask) {
  char a[32], b[32], c[32];
  printf("%s: PSNR %s dB, SSIM %s", lead, num(a, sizeof a, "%.3f", m->psnr), num(b, sizeof b, "%.4f", m->ssim));
  if (has_lpips) printf(", LPIPS %s", num(c, sizeof c, "%.4f", lpips[0]));
  if (has_mask)
    printf("; masked: PSNR %s dB, SSIM %s", num(a, sizeof a, "%.3f", m->psnr_fg), num(b, sizeof b, "%.4f", m->ssim_fg));
  if (has_mask && has_lpips) printf(", LPIPS %s", num(c, sizeof c, "%.4f", lpips[1]));
  printf("; detail %s (%s), %s (full image)\n", num(a, sizeof a, "%.3f", d->ratio), has_mask ? "mask" : "non-background",
         num(b, sizeof b, "%.3f", d->ratio_full));
}

static void json_num(FILE *f, const char *key, double v, int last) {
  if (isfinite(v)) fprintf(f, "\"%s\": %.10g%s", key, v, last ? "" : ", ");
  else fprintf(f, "\"%s\": null%s", key, last ? "" : ", ");
}

static void json_metrics(FILE *f, const spx_metrics *m, const spx_detail *d, const double *lpips, int has_mask) {
  json_num(f, "psnr", m->psnr, 0);
  json_num(f, "ssim", m->ssim, 0);
  if (has_mask) {
    json_num(f, "psnr_masked", m->psnr_fg, 0);
    json_num(f, "ssim_masked", m->ssim_fg, 0);
    json_num(f, "lpips_masked", lpips[1], 0);
  }
  json_num(f, "detail_full", d->ratio_full, 0);
  json_num(f, "detail", d->ratio, 0);
  json_num(f, "lpips", lpips[0], 1);
}

/* Write the report to path in the run's transaction (apps/cli_tx.h): F appears whole, when the
 * run succeeds, or not at all; an F that was there before a failed run stays as it was. */
static int write_json(spx_tx *tx, const char *path, const list *l, const spx_metrics *mean, const spx_detail *mean_d,
                      const double *mean_lpips, int has_mask) {
  const char *tmp = spx_tx_stage(tx, path);
  if (!tmp) return SPX_EXIT_ERROR; /* printed */
  FILE *f = fopen(tmp, "wb");
  if (!f) return spx_cli_errorf("eval", "%s: cannot write (%s)", path, strerror(errno));
  fprintf(f, "{\"count\": %d, ", l->n);
  json_metrics(f, mean, mean_d, mean_lpips, has_mask);
  fprintf(f, ",\n \"images\": [");
  for (int i = 0; i < l->n; i++) {
    fprintf(f, "%s\n  {\"name\": ", i ? "," : "");
    spx_cli_json_string(f, l->it[i].name);
    fprintf(f, ", ");
    json_metrics(f, &l->it[i].m, &l->it[i].d, l->it[i].lpips, has_mask);
    fprintf(f, "}");
  }
  fprintf(f, "\n ]}\n");
  int bad = ferror(f);
  bad |= fclose(f) != 0;
  if (bad) return spx_cli_errorf("eval", "%s: cannot write (%s)", path, strerror(errno ? errno : EIO));
  return spx_tx_commit(tx);
}

int spx_cmd_eval(int argc, char **argv) {
  const char *pred = NULL, *target = NULL, *mask = NULL, *json = NULL, *lpw = NULL, *device = NULL;
  int per_image = 0, no_lpips = 0;
  char cached[4096];
  spx_opt opts[] = {
      SPX_O(SPX_REQ, "--pred", SPX_OPT_IN, &pred, "P", "the predicted image, or a folder of them"),
      SPX_O(SPX_REQ, "--target", SPX_OPT_IN, &target, "T", "the target image, or a folder of them"),
      SPX_O(0, "--mask", SPX_OPT_IN, &mask, "M",
            "a mask file (for every image) or a folder of masks matched by name, the first channel nonzero = "
            "foreground: adds PSNR of the foreground pixels' MSE, the SSIM map and the lpips package's spatial "
            "LPIPS map averaged over the foreground"),
      SPX_O(0, "--per-image", SPX_OPT_FLAG, &per_image, NULL, "one line per image before the mean"),
      SPX_O(0, "--json", SPX_OPT_OUT, &json, "F",
            "write {\"count\", \"psnr\", \"ssim\", \"detail_full\", \"detail\", \"lpips\", \"images\": "
            "[{\"name\", \"psnr\", ..., \"lpips\"}]} (+ \"psnr_masked\", \"ssim_masked\", \"lpips_masked\" with "
            "--mask), null where a value is infinite, undefined or not asked for"),
      SPX_O(SPX_ALT(1), "--lpips", SPX_OPT_IN, &lpw, "W.safetensors",
            "LPIPS weights instead of the cached ones (tools/lpips_to_safetensors.py converts the lpips "
            "package's; images under 31x31: an error)"),
      SPX_O(SPX_ALT(1), "--no-lpips", SPX_OPT_FLAG, &no_lpips, NULL, "leave LPIPS out"),
      SPX_CLI_DEVICE_ROW(&device),
      SPX_O_END};
  int parsed = spx_cli_parse(argc, argv, "eval", ABOUT, opts);
  if (parsed >= 0) return parsed;
  if (lpw && no_lpips) return spx_cli_usage("eval", "give --lpips W or --no-lpips, not both");
  int lp_opt = !lpw && !no_lpips && spx_weights_path(SPX_WEIGHTS_LPIPS_ALEX, cached, sizeof cached) == 1;
  if (lp_opt) lpw = cached;
  if (spx_cli_only_with(opts, "eval", "--device", lpw != NULL, "LPIPS (--lpips, or the cached weights of make weights)"))
    return SPX_EXIT_USAGE;
  spx_ctx *ctx = NULL;
  spx_lpips *lp = NULL;
  list l = {0};
  int rc;
  spx_tx tx;
  if (spx_ctx_create(&ctx)) return spx_cli_errorf("eval", "out of memory");
  spx_tx_begin(&tx, "eval", 0);
  if (json && (rc = spx_tx_check(&tx, json))) goto done; /* before any work */
  if ((rc = pair_up(pred, target, mask, &l))) goto done;
  if (lpw) {
    if ((rc = spx_cli_open_device("eval", ctx, device))) goto done;
    if (spx_lpips_load(ctx, lpw, &lp)) {
      rc = lp_opt ? spx_cli_errorf("eval", "%s (the cached LPIPS weights: `make weights` makes them again, --no-lpips "
                                   "skips LPIPS)", spx_ctx_message(ctx))
                  : spx_cli_error("eval", ctx);
      goto done;
    }
  }
  spx_metrics mean = {0};
  spx_detail mean_d = {0};
  double mean_lp[2] = {0, 0};
  for (int i = 0; i < l.n; i++) {
    item *it = &l.it[i];
    if ((rc = measure(ctx, lp, lp_opt, it))) goto done;
    if (per_image) print_line(it->name, &it->m, &it->d, it->lpips, lp != NULL, mask != NULL);
    mean.psnr += it->m.psnr, mean.ssim += it->m.ssim, mean.psnr_fg += it->m.psnr_fg, mean.ssim_fg += it->m.ssim_fg;
    mean_d.ratio += it->d.ratio, mean_d.ratio_full += it->d.ratio_full;
    mean_lp[0] += it->lpips[0], mean_lp[1] += it->lpips[1];
  }
  mean.psnr /= l.n, mean.ssim /= l.n, mean.psnr_fg /= l.n, mean.ssim_fg /= l.n;
  mean_d.ratio /= l.n, mean_d.ratio_full /= l.n;
  mean_lp[0] = lp ? mean_lp[0] / l.n : NAN;
  mean_lp[1] = lp && mask ? mean_lp[1] / l.n : NAN;
  if (json && (rc = write_json(&tx, json, &l, &mean, &mean_d, mean_lp, mask != NULL))) goto done;
  char lead[64];
  snprintf(lead, sizeof lead, "mean over %d images", l.n); /* the fixed form of the design, also for 1 */
  print_line(lead, &mean, &mean_d, mean_lp, lp != NULL, mask != NULL);
done:
  spx_tx_end(&tx);
  spx_lpips_free(lp);
  list_free(&l);
  spx_ctx_destroy(ctx);
  return rc;
}
