/* Line-plot writer, see plot.h. */
#include "plot.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "smplpix/core.h"
#include "smplpix/image.h"

/* ---- 5x7 bitmap font: printable ASCII 32..126, one row string per pixel row ('#' = ink).
 * g, p, q and y are drawn 2 rows lower (5-row x-height + 2-row descender), so a line of
 * text is 9 rows tall; j keeps its hook inside the box. ---- */
static const char *const FONT[95][7] = {
    {".....", ".....", ".....", ".....", ".....", ".....", "....."}, /* ' ' */
    {"..#..", "..#..", "..#..", "..#..", "..#..", ".....", "..#.."}, /* ! */
    {".#.#.", ".#.#.", ".....", ".....", ".....", ".....", "....."}, /* " */
    {".#.#.", ".#.#.", "#####", ".#.#.", "#####", ".#.#.", ".#.#."}, /* # */
    {"..#..", ".####", "#.#..", ".###.", "..#.#", "####.", "..#.."}, /* $ */
    {"##...", "##..#", "...#.", "..#..", ".#...", "#..##", "...##"}, /* % */
    {".##..", "#..#.", "#.#..", ".#...", "#.#.#", "#..#.", ".##.#"}, /* & */
    {"..#..", "..#..", ".....", ".....", ".....", ".....", "....."}, /* ' */
    {"...#.", "..#..", ".#...", ".#...", ".#...", "..#..", "...#."}, /* ( */
    {".#...", "..#..", "...#.", "...#.", "...#.", "..#..", ".#..."}, /* ) */
    {".....", "..#..", "#.#.#", ".###.", "#.#.#", "..#..", "....."}, /* * */
    {".....", "..#..", "..#..", "#####", "..#..", "..#..", "....."}, /* + */
    {".....", ".....", ".....", ".....", "..##.", "..#..", ".#..."}, /* , */
    {".....", ".....", ".....", "#####", ".....", ".....", "....."}, /* - */
    {".....", ".....", ".....", ".....", ".....", ".##..", ".##.."}, /* . */
    {".....", "....#", "...#.", "..#..", ".#...", "#....", "....."}, /* / */
    {".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###."}, /* 0 */
    {"..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###."}, /* 1 */
    {".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####"}, /* 2 */
    {"#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###."}, /* 3 */
    {"...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#."}, /* 4 */
    {"#####", "#....", "####.", "....#", "....#", "#...#", ".###."}, /* 5 */
    {"..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###."}, /* 6 */
    {"#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#..."}, /* 7 */
    {".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###."}, /* 8 */
    {".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##.."}, /* 9 */
    {".....", ".##..", ".##..", ".....", ".##..", ".##..", "....."}, /* : */
    {".....", ".##..", ".##..", ".....", ".##..", "..#..", ".#..."}, /* ; */
    {"...#.", "..#..", ".#...", "#....", ".#...", "..#..", "...#."}, /* < */
    {".....", ".....", "#####", ".....", "#####", ".....", "....."}, /* = */
    {".#...", "..#..", "...#.", "....#", "...#.", "..#..", ".#..."}, /* > */
    {".###.", "#...#", "....#", "...#.", "..#..", ".....", "..#.."}, /* ? */
    {".###.", "#...#", "....#", ".##.#", "#.#.#", "#.#.#", ".###."}, /* @ */
    {".###.", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"}, /* A */
    {"####.", "#...#", "#...#", "####.", "#...#", "#...#", "####."}, /* B */
    {".###.", "#...#", "#....", "#....", "#....", "#...#", ".###."}, /* C */
    {"###..", "#..#.", "#...#", "#...#", "#...#", "#..#.", "###.."}, /* D */
    {"#####", "#....", "#....", "####.", "#....", "#....", "#####"}, /* E */
    {"#####", "#....", "#....", "####.", "#....", "#....", "#...."}, /* F */
    {".###.", "#...#", "#....", "#.###", "#...#", "#...#", ".####"}, /* G */
    {"#...#", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"}, /* H */
    {".###.", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."}, /* I */
    {"..###", "...#.", "...#.", "...#.", "...#.", "#..#.", ".##.."}, /* J */
    {"#...#", "#..#.", "#.#..", "##...", "#.#..", "#..#.", "#...#"}, /* K */
    {"#....", "#....", "#....", "#....", "#....", "#....", "#####"}, /* L */
    {"#...#", "##.##", "#.#.#", "#.#.#", "#...#", "#...#", "#...#"}, /* M */
    {"#...#", "#...#", "##..#", "#.#.#", "#..##", "#...#", "#...#"}, /* N */
    {".###.", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."}, /* O */
    {"####.", "#...#", "#...#", "####.", "#....", "#....", "#...."}, /* P */
    {".###.", "#...#", "#...#", "#...#", "#.#.#", "#..#.", ".##.#"}, /* Q */
    {"####.", "#...#", "#...#", "####.", "#.#..", "#..#.", "#...#"}, /* R */
    {".####", "#....", "#....", ".###.", "....#", "....#", "####."}, /* S */
    {"#####", "..#..", "..#..", "..#..", "..#..", "..#..", "..#.."}, /* T */
    {"#...#", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."}, /* U */
    {"#...#", "#...#", "#...#", "#...#", "#...#", ".#.#.", "..#.."}, /* V */
    {"#...#", "#...#", "#...#", "#.#.#", "#.#.#", "#.#.#", ".#.#."}, /* W */
    {"#...#", "#...#", ".#.#.", "..#..", ".#.#.", "#...#", "#...#"}, /* X */
    {"#...#", "#...#", ".#.#.", "..#..", "..#..", "..#..", "..#.."}, /* Y */
    {"#####", "....#", "...#.", "..#..", ".#...", "#....", "#####"}, /* Z */
    {".###.", ".#...", ".#...", ".#...", ".#...", ".#...", ".###."}, /* [ */
    {".....", "#....", ".#...", "..#..", "...#.", "....#", "....."}, /* backslash */
    {".###.", "...#.", "...#.", "...#.", "...#.", "...#.", ".###."}, /* ] */
    {"..#..", ".#.#.", "#...#", ".....", ".....", ".....", "....."}, /* ^ */
    {".....", ".....", ".....", ".....", ".....", ".....", "#####"}, /* _ */
    {".#...", "..#..", ".....", ".....", ".....", ".....", "....."}, /* ` */
    {".....", ".....", ".###.", "....#", ".####", "#...#", ".####"}, /* a */
    {"#....", "#....", "#.##.", "##..#", "#...#", "#...#", "####."}, /* b */
    {".....", ".....", ".###.", "#....", "#....", "#...#", ".###."}, /* c */
    {"....#", "....#", ".##.#", "#..##", "#...#", "#...#", ".####"}, /* d */
    {".....", ".....", ".###.", "#...#", "#####", "#....", ".###."}, /* e */
    {"..##.", ".#..#", ".#...", "###..", ".#...", ".#...", ".#..."}, /* f */
    {".####", "#...#", "#...#", "#...#", ".####", "....#", ".###."}, /* g (descends) */
    {"#....", "#....", "#.##.", "##..#", "#...#", "#...#", "#...#"}, /* h */
    {"..#..", ".....", ".##..", "..#..", "..#..", "..#..", ".###."}, /* i */
    {"...#.", ".....", "..##.", "...#.", "...#.", "#..#.", ".##.."}, /* j */
    {"#....", "#....", "#..#.", "#.#..", "##...", "#.#..", "#..#."}, /* k */
    {".##..", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."}, /* l */
    {".....", ".....", "##.#.", "#.#.#", "#.#.#", "#...#", "#...#"}, /* m */
    {".....", ".....", "#.##.", "##..#", "#...#", "#...#", "#...#"}, /* n */
    {".....", ".....", ".###.", "#...#", "#...#", "#...#", ".###."}, /* o */
    {"####.", "#...#", "#...#", "#...#", "####.", "#....", "#...."}, /* p (descends) */
    {".####", "#...#", "#...#", "#...#", ".####", "....#", "....#"}, /* q (descends) */
    {".....", ".....", "#.##.", "##..#", "#....", "#....", "#...."}, /* r */
    {".....", ".....", ".####", "#....", ".###.", "....#", "####."}, /* s */
    {".#...", ".#...", "###..", ".#...", ".#...", ".#..#", "..##."}, /* t */
    {".....", ".....", "#...#", "#...#", "#...#", "#..##", ".##.#"}, /* u */
    {".....", ".....", "#...#", "#...#", "#...#", ".#.#.", "..#.."}, /* v */
    {".....", ".....", "#...#", "#...#", "#.#.#", "#.#.#", ".#.#."}, /* w */
    {".....", ".....", "#...#", ".#.#.", "..#..", ".#.#.", "#...#"}, /* x */
    {"#...#", "#...#", "#...#", "#...#", ".####", "....#", ".###."}, /* y (descends) */
    {".....", ".....", "#####", "...#.", "..#..", ".#...", "#####"}, /* z */
    {"...#.", "..#..", "..#..", ".#...", "..#..", "..#..", "...#."}, /* { */
    {"..#..", "..#..", "..#..", "..#..", "..#..", "..#..", "..#.."}, /* | */
    {".#...", "..#..", "..#..", "...#.", "..#..", "..#..", ".#..."}, /* } */
    {".....", ".....", ".#...", "#.#.#", "...#.", ".....", "....."}, /* ~ */
};

/* ---- pixels ---- */
typedef struct canvas {
  float *px; /* HWC RGB */
  int w, h;
  int cx0, cy0, cx1, cy1; /* clip rectangle, inclusive */
} canvas;

static void blend(canvas *c, int x, int y, const float col[3], float a) {
  if (x < c->cx0 || x > c->cx1 || y < c->cy0 || y > c->cy1 || a <= 0) return;
  if (a > 1) a = 1;
  float *p = c->px + 3 * ((size_t)y * (size_t)c->w + (size_t)x);
  for (int k = 0; k < 3; k++) p[k] = p[k] * (1 - a) + col[k] * a;
}

static void fill_rect(canvas *c, int x0, int y0, int x1, int y1, const float col[3]) {
  for (int y = y0; y <= y1; y++)
    for (int x = x0; x <= x1; x++) blend(c, x, y, col, 1);
}

static void rect_outline(canvas *c, int x0, int y0, int x1, int y1, const float col[3]) {
  fill_rect(c, x0, y0, x1, y0, col);
  fill_rect(c, x0, y1, x1, y1, col);
  fill_rect(c, x0, y0, x0, y1, col);
  fill_rect(c, x1, y0, x1, y1, col);
}

/* Antialiased thick segment: coverage from the distance of each pixel centre to the segment. */
static void segment(canvas *c, double x0, double y0, double x1, double y1, double half, const float col[3]) {
  int bx0 = (int)floor(fmin(x0, x1) - half - 1), bx1 = (int)ceil(fmax(x0, x1) + half + 1);
  int by0 = (int)floor(fmin(y0, y1) - half - 1), by1 = (int)ceil(fmax(y0, y1) + half + 1);
  double dx = x1 - x0, dy = y1 - y0, len2 = dx * dx + dy * dy;
  for (int y = by0; y <= by1; y++)
    for (int x = bx0; x <= bx1; x++) {
      double t = len2 > 0 ? ((x - x0) * dx + (y - y0) * dy) / len2 : 0;
      t = t < 0 ? 0 : t > 1 ? 1 : t;
      double ex = x - (x0 + t * dx), ey = y - (y0 + t * dy);
      double a = half + 0.5 - sqrt(ex * ex + ey * ey);
      if (a > 0) {
        /* a pixel shared by two segments of one polyline is painted once at full coverage */
        blend(c, x, y, col, (float)(a > 1 ? 1 : a));
      }
    }
}

enum { MK_CIRCLE, MK_SQUARE, MK_TRIANGLE, MK_DIAMOND, MK_TRIANGLE_DOWN, MK_COUNT };

static int marker_inside(int shape, double dx, double dy, double r) {
  switch (shape) {
  case MK_CIRCLE: return dx * dx + dy * dy <= r * r;
  case MK_SQUARE: return fabs(dx) <= 0.85 * r && fabs(dy) <= 0.85 * r;
  case MK_DIAMOND: return fabs(dx) + fabs(dy) <= 1.2 * r;
  case MK_TRIANGLE:
  case MK_TRIANGLE_DOWN: {
    double yy = shape == MK_TRIANGLE ? dy : -dy; /* apex up (screen y down) */
    double top = -1.1 * r, bot = 0.8 * r;
    if (yy < top || yy > bot) return 0;
    double half = 1.1 * r * (yy - top) / (bot - top);
    return fabs(dx) <= half;
  }
  }
  return 0;
}

/* Filled marker with a 4x4 supersampled edge, outlined in white so overlapping markers separate. */
static void marker(canvas *c, double cx, double cy, int shape, double r, const float col[3]) {
  static const float white[3] = {1, 1, 1};
  int x0 = (int)floor(cx - r - 3), x1 = (int)ceil(cx + r + 3), y0 = (int)floor(cy - r - 3), y1 = (int)ceil(cy + r + 3);
  for (int pass = 0; pass < 2; pass++) {
    double rr = pass == 0 ? r + 1.3 : r;
    for (int y = y0; y <= y1; y++)
      for (int x = x0; x <= x1; x++) {
        int hit = 0;
        for (int sy = 0; sy < 4; sy++)
          for (int sx = 0; sx < 4; sx++)
            hit += marker_inside(shape, x + (sx + 0.5) / 4 - 0.5 - cx, y + (sy + 0.5) / 4 - 0.5 - cy, rr);
        blend(c, x, y, pass == 0 ? white : col, hit / 16.0f);
      }
  }
}

/* ---- text ---- */
int plot_text_width(const char *s, int scale) {
  size_t n = s ? strlen(s) : 0;
  return n ? (int)(6 * n - 1) * scale : 0;
}

static void text(canvas *c, int x, int y, const char *s, int scale, const float col[3], int rotate) {
  if (!s) return;
  int tw = plot_text_width(s, scale);
  for (size_t i = 0; s[i]; i++) {
    unsigned char ch = (unsigned char)s[i];
    const char *const *g = FONT[(ch >= 32 && ch <= 126 ? ch : '?') - 32];
    int drop = (ch == 'g' || ch == 'p' || ch == 'q' || ch == 'y') ? 2 * scale : 0;
    for (int gy = 0; gy < 7 * scale; gy++)
      for (int gx = 0; gx < 5 * scale; gx++) {
        if (g[gy / scale][gx / scale] != '#') continue;
        int tx = (int)(6 * i) * scale + gx; /* position along the text */
        if (rotate)
          blend(c, x + gy + drop, y + (tw - 1 - tx), col, 1);
        else
          blend(c, x + tx, y + gy + drop, col, 1);
      }
  }
}

void plot_draw_text(float *rgb, int w, int h, int x, int y, const char *s, int scale, const float color[3],
                    int rotate) {
  canvas c = {rgb, w, h, 0, 0, w - 1, h - 1};
  text(&c, x, y, s, scale < 1 ? 1 : scale, color, rotate);
}

/* ---- the plot ---- */
typedef struct series {
  char name[64];
  int n;
  double *x, *y;
} series;

struct plot {
  int w, h, logx, logy;
  char title[128], xlabel[96], ylabel[96];
  int ns;
  series s[PLOT_MAX_SERIES];
};

plot *plot_create(int w, int h, const char *title, const char *xlabel, const char *ylabel, int logx, int logy) {
  if (w < 160 || h < 120 || w > 8192 || h > 8192) return NULL;
  plot *p = calloc(1, sizeof *p);
  if (!p) return NULL;
  p->w = w, p->h = h, p->logx = !!logx, p->logy = !!logy;
  snprintf(p->title, sizeof p->title, "%s", title ? title : "");
  snprintf(p->xlabel, sizeof p->xlabel, "%s", xlabel ? xlabel : "");
  snprintf(p->ylabel, sizeof p->ylabel, "%s", ylabel ? ylabel : "");
  return p;
}

int plot_series(plot *p, const char *name, int n, const double *xs, const double *ys) {
  if (!p || n < 0 || n > 1000000 || (n > 0 && (!xs || !ys)) || p->ns >= PLOT_MAX_SERIES) return -1;
  series *s = &p->s[p->ns];
  s->x = malloc(sizeof(double) * (size_t)(n ? n : 1));
  s->y = malloc(sizeof(double) * (size_t)(n ? n : 1));
  if (!s->x || !s->y) {
    free(s->x), free(s->y);
    s->x = s->y = NULL;
    return -1;
  }
  if (n) memcpy(s->x, xs, sizeof(double) * (size_t)n), memcpy(s->y, ys, sizeof(double) * (size_t)n);
  s->n = n;
  snprintf(s->name, sizeof s->name, "%s", name ? name : "");
  p->ns++;
  return 0;
}

void plot_free(plot *p) {
  if (!p) return;
  for (int i = 0; i < p->ns; i++) free(p->s[i].x), free(p->s[i].y);
  free(p);
}

static int usable(double v, int logscale) { return isfinite(v) && (!logscale || v > 0); }

typedef struct axis {
  int log;
  double lo, hi; /* in axis units (log10 of the value on a log axis) */
  int n;
  double t[128];     /* tick positions, axis units */
  int labeled[128];  /* major tick: label + grid line */
  char lab[128][24];
} axis;

static void fmt_value(char *buf, size_t cap, double v) {
  double a = fabs(v);
  if (a >= 1e6 && fmod(a, 1e6) == 0)
    snprintf(buf, cap, "%gM", v / 1e6);
  else if (a >= 1e4 && fmod(a, 1e3) == 0)
    snprintf(buf, cap, "%gk", v / 1e3);
  else
    snprintf(buf, cap, "%g", v);
}

/* Data range [dlo, dhi] (axis units) → padded range and ticks. */
static void make_axis(axis *a, double dlo, double dhi, int logscale) {
  a->log = logscale;
  a->n = 0;
  if (logscale) {
    if (!(dhi > dlo)) dlo -= 0.3, dhi += 0.3;
    double pad = fmax(0.04 * (dhi - dlo), 0.05);
    a->lo = dlo - pad, a->hi = dhi + pad;
    double span = a->hi - a->lo;
    for (int k = (int)floor(a->lo); k <= (int)ceil(a->hi) && a->n < 128; k++)
      for (int m = 1; m <= 9 && a->n < 128; m++) {
        double t = k + log10((double)m);
        if (t < a->lo - 1e-12 || t > a->hi + 1e-12) continue;
        int major = m == 1 || (span <= 2.5 && (m == 2 || m == 5)) || (span <= 0.8 && m == 3);
        a->t[a->n] = t;
        a->labeled[a->n] = major && (span <= 7 || k % 2 == 0);
        fmt_value(a->lab[a->n], sizeof a->lab[0], m * pow(10.0, k));
        a->n++;
      }
    return;
  }
  if (dlo > 0 && dhi > 0) dlo = 0; /* linear axes start at zero for one-signed data */
  if (dlo < 0 && dhi < 0) dhi = 0;
  if (!(dhi > dlo)) dlo -= 1, dhi += 1;
  double raw = (dhi - dlo) / 5, mag = pow(10.0, floor(log10(raw))), f = raw / mag;
  double step = (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10) * mag;
  a->lo = floor(dlo / step) * step;
  a->hi = ceil(dhi * 1.02 / step) * step;
  for (double t = a->lo; t <= a->hi + 0.5 * step && a->n < 128; t += step) {
    double v = round(t / step) * step;
    if (fabs(v) < 1e-9 * step) v = 0;
    a->t[a->n] = v;
    a->labeled[a->n] = 1;
    fmt_value(a->lab[a->n], sizeof a->lab[0], v);
    a->n++;
  }
}

typedef struct frame {
  int x0, y0, x1, y1; /* plot area, inclusive */
  axis ax, ay;
} frame;

static double map_x(const frame *f, double v) {
  double t = f->ax.log ? log10(v) : v;
  return f->x0 + (t - f->ax.lo) / (f->ax.hi - f->ax.lo) * (f->x1 - f->x0);
}
static double map_y(const frame *f, double v) {
  double t = f->ay.log ? log10(v) : v;
  return f->y1 - (t - f->ay.lo) / (f->ay.hi - f->ay.lo) * (f->y1 - f->y0);
}

static const float PALETTE[8][3] = {
    {0.12f, 0.47f, 0.71f}, {1.00f, 0.50f, 0.05f}, {0.17f, 0.63f, 0.17f}, {0.84f, 0.15f, 0.16f},
    {0.58f, 0.40f, 0.74f}, {0.55f, 0.34f, 0.29f}, {0.89f, 0.47f, 0.76f}, {0.50f, 0.50f, 0.50f},
};

/* How many sampled data points fall in a box (legend placement). */
static int data_in_box(const plot *p, const frame *f, int bx0, int by0, int bx1, int by1) {
  int hits = 0;
  for (int i = 0; i < p->ns; i++) {
    const series *s = &p->s[i];
    double px = 0, py = 0;
    int have = 0;
    for (int j = 0; j < s->n; j++) {
      if (!usable(s->x[j], p->logx) || !usable(s->y[j], p->logy)) {
        have = 0;
        continue;
      }
      double qx = map_x(f, s->x[j]), qy = map_y(f, s->y[j]);
      int steps = have ? 1 + (int)(hypot(qx - px, qy - py) / 2) : 1;
      for (int k = 0; k <= steps; k++) {
        double t = have ? (double)k / steps : 1, x = px + t * (qx - px), y = py + t * (qy - py);
        hits += x >= bx0 - 6 && x <= bx1 + 6 && y >= by0 - 6 && y <= by1 + 6;
      }
      px = qx, py = qy, have = 1;
    }
  }
  return hits;
}

/* The axes of the data's ranges (log10 on a log axis; unit ranges without usable data). */
static void data_axes(const plot *p, frame *f) {
  double xlo = INFINITY, xhi = -INFINITY, ylo = INFINITY, yhi = -INFINITY;
  for (int i = 0; i < p->ns; i++)
    for (int j = 0; j < p->s[i].n; j++) {
      double x = p->s[i].x[j], y = p->s[i].y[j];
      if (!usable(x, p->logx) || !usable(y, p->logy)) continue;
      x = p->logx ? log10(x) : x, y = p->logy ? log10(y) : y;
      xlo = fmin(xlo, x), xhi = fmax(xhi, x), ylo = fmin(ylo, y), yhi = fmax(yhi, y);
    }
  if (!(xlo <= xhi)) xlo = p->logx ? 0 : 0, xhi = p->logx ? 1 : 1, ylo = p->logy ? 0 : 0, yhi = p->logy ? 1 : 1;
  make_axis(&f->ax, xlo, xhi, p->logx);
  make_axis(&f->ay, ylo, yhi, p->logy);
}

/* The plot area inside the title, the axis labels and the tick labels; -1 when too small. */
static int layout(const plot *p, frame *f) {
  int ylab_w = 0;
  for (int i = 0; i < f->ay.n; i++)
    if (f->ay.labeled[i]) {
      int tw = plot_text_width(f->ay.lab[i], 1);
      ylab_w = tw > ylab_w ? tw : ylab_w;
    }
  int title_h = p->title[0] ? 14 + 14 : 10;
  f->x0 = 10 + (p->ylabel[0] ? 7 + 10 : 0) + ylab_w + 10;
  f->y0 = title_h;
  f->x1 = p->w - 1 - 16;
  f->y1 = p->h - 1 - (10 + 7 + (p->xlabel[0] ? 10 + 7 : 0) + 10);
  return f->x1 - f->x0 < 40 || f->y1 - f->y0 < 40 ? -1 : 0;
}

static const float BLACK[3] = {0, 0, 0};

/* grid, ticks, tick labels, the frame, the title and the axis labels */
static void draw_axes(canvas *c, const plot *p, const frame *f) {
  const float grid[3] = {0.88f, 0.88f, 0.88f}, grey[3] = {0.35f, 0.35f, 0.35f};
  for (int i = 0; i < f->ax.n; i++) {
    int x = (int)lround(f->x0 + (f->ax.t[i] - f->ax.lo) / (f->ax.hi - f->ax.lo) * (f->x1 - f->x0));
    if (f->ax.labeled[i]) {
      fill_rect(c, x, f->y0 + 1, x, f->y1 - 1, grid);
      int tw = plot_text_width(f->ax.lab[i], 1);
      text(c, x - tw / 2, f->y1 + 8, f->ax.lab[i], 1, BLACK, 0);
    }
    fill_rect(c, x, f->y1 + 1, x, f->y1 + (f->ax.labeled[i] ? 5 : 3), BLACK);
  }
  for (int i = 0; i < f->ay.n; i++) {
    int y = (int)lround(f->y1 - (f->ay.t[i] - f->ay.lo) / (f->ay.hi - f->ay.lo) * (f->y1 - f->y0));
    if (f->ay.labeled[i]) {
      fill_rect(c, f->x0 + 1, y, f->x1 - 1, y, grid);
      int tw = plot_text_width(f->ay.lab[i], 1);
      text(c, f->x0 - 8 - tw, y - 3, f->ay.lab[i], 1, BLACK, 0);
    }
    fill_rect(c, f->x0 - (f->ay.labeled[i] ? 5 : 3), y, f->x0 - 1, y, BLACK);
  }
  rect_outline(c, f->x0, f->y0, f->x1, f->y1, BLACK);
  if (p->title[0]) text(c, (p->w - plot_text_width(p->title, 2)) / 2, 8, p->title, 2, BLACK, 0);
  if (p->xlabel[0])
    text(c, (f->x0 + f->x1 - plot_text_width(p->xlabel, 1)) / 2, f->y1 + 8 + 7 + 10, p->xlabel, 1, grey, 0);
  if (p->ylabel[0]) text(c, 10, (f->y0 + f->y1 - plot_text_width(p->ylabel, 1)) / 2, p->ylabel, 1, grey, 1);
}

/* the series' lines and markers, clipped to the plot area */
static void draw_series(canvas *c, const plot *p, const frame *f) {
  c->cx0 = f->x0 + 1, c->cy0 = f->y0 + 1, c->cx1 = f->x1 - 1, c->cy1 = f->y1 - 1;
  for (int i = 0; i < p->ns; i++) {
    const series *s = &p->s[i];
    const float *col = PALETTE[i % 8];
    for (int j = 1; j < s->n; j++)
      if (usable(s->x[j - 1], p->logx) && usable(s->y[j - 1], p->logy) && usable(s->x[j], p->logx) &&
          usable(s->y[j], p->logy))
        segment(c, map_x(f, s->x[j - 1]), map_y(f, s->y[j - 1]), map_x(f, s->x[j]), map_y(f, s->y[j]), 0.9, col);
    for (int j = 0; j < s->n; j++)
      if (usable(s->x[j], p->logx) && usable(s->y[j], p->logy))
        marker(c, map_x(f, s->x[j]), map_y(f, s->y[j]), i % MK_COUNT, 3.6, col);
  }
}

/* the legend, in the corner with the least data under it */
static void draw_legend(canvas *c, const plot *p, const frame *f) {
  if (p->ns <= 0) return;
  int name_w = 0;
  for (int i = 0; i < p->ns; i++) {
    int tw = plot_text_width(p->s[i].name, 1);
    name_w = tw > name_w ? tw : name_w;
  }
  int lw = 8 + 26 + 8 + name_w + 8, lh = 6 + 14 * p->ns;
  /* the four corners first; if none is empty, any height along the left or right edge */
  int best_hits = -1, lx = f->x0 + 8, ly = f->y0 + 8;
  int cand[4][2] = {{f->x0 + 8, f->y0 + 8},
                    {f->x1 - 8 - lw, f->y0 + 8},
                    {f->x0 + 8, f->y1 - 8 - lh},
                    {f->x1 - 8 - lw, f->y1 - 8 - lh}};
  for (int k = 0; k < 4; k++) {
    int hits = data_in_box(p, f, cand[k][0], cand[k][1], cand[k][0] + lw, cand[k][1] + lh);
    if (best_hits < 0 || hits < best_hits) lx = cand[k][0], ly = cand[k][1], best_hits = hits;
  }
  for (int y = f->y0 + 8; best_hits > 0 && y <= f->y1 - 8 - lh; y += 4)
    for (int side = 0; side < 2; side++) {
      int x = side ? f->x1 - 8 - lw : f->x0 + 8;
      int hits = data_in_box(p, f, x, y, x + lw, y + lh);
      if (hits < best_hits) lx = x, ly = y, best_hits = hits;
    }
  const float white[3] = {1, 1, 1}, frame_col[3] = {0.6f, 0.6f, 0.6f};
  fill_rect(c, lx, ly, lx + lw, ly + lh, white);
  rect_outline(c, lx, ly, lx + lw, ly + lh, frame_col);
  for (int i = 0; i < p->ns; i++) {
    const float *col = PALETTE[i % 8];
    double cy = ly + 10 + 14 * i;
    segment(c, lx + 8, cy, lx + 8 + 26, cy, 0.9, col);
    marker(c, lx + 8 + 13, cy, i % MK_COUNT, 3.6, col);
    text(c, lx + 8 + 26 + 8, (int)cy - 3, p->s[i].name, 1, BLACK, 0);
  }
}

int plot_save(const plot *p, const char *path, char *err, size_t cap) {
  if (!p || !path) {
    if (err && cap) snprintf(err, cap, "plot_save: no plot or no path");
    return -1;
  }
  int W = p->w, H = p->h, ret = -1;
  spx_ctx *ctx = NULL;
  spx_image img = {W, H, 3, NULL};
  img.data = malloc(sizeof(float) * 3 * (size_t)W * (size_t)H);
  if (!img.data) {
    if (err && cap) snprintf(err, cap, "plot_save: out of memory");
    return -1;
  }
  for (size_t i = 0; i < 3 * (size_t)W * (size_t)H; i++) img.data[i] = 1.0f;
  canvas c = {img.data, W, H, 0, 0, W - 1, H - 1};
  frame f;
  data_axes(p, &f);
  if (layout(p, &f)) {
    if (err && cap) snprintf(err, cap, "plot_save: %dx%d is too small for the labels", W, H);
    goto done;
  }
  draw_axes(&c, p, &f);
  draw_series(&c, p, &f);
  draw_legend(&c, p, &f);
  if (spx_ctx_create(&ctx)) {
    if (err && cap) snprintf(err, cap, "plot_save: out of memory");
    goto done;
  }
  if (spx_png_write(ctx, path, &img)) {
    if (err && cap) snprintf(err, cap, "%s", spx_ctx_message(ctx));
    goto done;
  }
  ret = 0;
done:
  spx_ctx_destroy(ctx);
  free(img.data);
  return ret;
}
