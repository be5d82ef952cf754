/* A tiny line-plot writer for benchmark results: axes with ticks and grid, linear or log10 axes,
 * one polyline with markers per series (distinct colours and marker shapes), a legend placed in
 * the emptiest corner, text in a built-in 5x7 bitmap font (printable ASCII), saved as an 8-bit
 * RGB PNG through spx_png_write. Benchmark code, not library code.
 *
 *   plot *p = plot_create(640, 420, "Mesh raster, 410x308", "vertices", "ms per frame", 1, 1);
 *   plot_series(p, "llvmpipe", 3, xs, ys);
 *   plot_save(p, "out/bench/llvmpipe.png", err, sizeof err);
 *   plot_free(p);
 *
 * Points that are not finite, or not positive on a log axis, are left out (the line breaks). */
#ifndef SPX_BENCH_PLOT_H
#define SPX_BENCH_PLOT_H

#include <stddef.h>

typedef struct plot plot;

/* w, h in pixels (at least 160 x 120, at most 8192 x 8192); title/labels may be NULL or "";
 * logx / logy nonzero for log10 axes. NULL on bad arguments or out of memory. */
plot *plot_create(int w, int h, const char *title, const char *xlabel, const char *ylabel, int logx, int logy);
/* Add a series (copied). Returns 0, or -1 (bad arguments, more than PLOT_MAX_SERIES, memory). */
#define PLOT_MAX_SERIES 16
int plot_series(plot *p, const char *name, int n, const double *xs, const double *ys);
/* Render and write a PNG (atomically, via spx_png_write). 0, or -1 with a reason in err. */
int plot_save(const plot *p, const char *path, char *err, size_t cap);
void plot_free(plot *p);

/* Text helpers (also used by plot_save): width in pixels of s at `scale` (6*scale per character,
 * minus the trailing gap), and drawing into an HWC RGB float image; rotate = 1 draws upwards
 * (90 degrees counter-clockwise), (x, y) being the top-left of the unrotated text. */
int plot_text_width(const char *s, int scale);
void plot_draw_text(float *rgb, int w, int h, int x, int y, const char *s, int scale, const float color[3],
                    int rotate);

#endif
