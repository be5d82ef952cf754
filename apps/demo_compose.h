/* Side-by-side strip of labelled images for `smplpix demo` (apps/cmd_demo.c). */
#ifndef SPX_APPS_DEMO_COMPOSE_H
#define SPX_APPS_DEMO_COMPOSE_H

#include "smplpix/smplpix.h"

/* n images of one size (3 or 4 channels; RGB used, clamped to [0,1]) side by side, 2-pixel grey
 * gaps, under a white band with each label (the built-in 5x7 font, spx_synth_glyph_pixel,
 * scaled 1x per 96 pixels of height) centred over its image; every image enlarged zoom times
 * (nearest pixel; zoom 1..8). out: RGB, allocated here. */
spx_status spx_demo_compose(spx_ctx *ctx, const spx_image *const *imgs, const char *const *labels, int n, int zoom,
                            spx_image *out);

/* The size spx_demo_compose gives n images of w x h at zoom (checked before the work). */
void spx_demo_strip_size(int n, int w, int h, int zoom, long *tw, long *th);

#endif
