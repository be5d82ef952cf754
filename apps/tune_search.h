/* The search of `smplpix tune` (apps/tune_search.c). */
#ifndef SPX_APPS_TUNE_SEARCH_H
#define SPX_APPS_TUNE_SEARCH_H

#include <stdio.h>

#include "smplpix/smplpix.h"

#define SPX_TUNE_MAXB 8 /* batches in one search */

typedef struct spx_tune_plan {
  int quick;      /* a few candidates per tunable instead of the full lists */
  int h, w;       /* image size of the UNet input */
  int nwidths;    /* base widths to time */
  int widths[8];
  int nbatches;   /* batches to time; every (width, batch) pair is timed and the score is the mean
                   * over the pairs of time / the incumbent's */
  int batches[SPX_TUNE_MAXB];
  int repeat;     /* timed runs per candidate and pair; the minimum counts */
  const char *device; /* the spec ctx was opened with (a second context opens the same device) */
  int cpu_clock;      /* time by this process's CPU time instead of wall time */
} spx_tune_plan;

/* Run the search on ctx's open device, print the table to out, write the tuning file. Returns
 * an exit code (errors printed). */
int spx_tune_search(spx_ctx *ctx, const spx_tune_plan *plan, FILE *out);

#endif
