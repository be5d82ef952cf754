/* The writing side of `smplpix synth` (apps/synth_out.c): inputs, folder, photos, manifest. */
#ifndef SPX_APPS_SYNTH_OUT_H
#define SPX_APPS_SYNTH_OUT_H

#include <stdint.h>

typedef struct synth_opts {
  int subjects, views;
  uint64_t seed;
  int width, height;
  int32_t tex_size;
  const char *out, *body_path, *bvh_path, *parts_path, *device;
  int force, progress;
} synth_opts;

/* Validate the inputs, then write the whole output folder (or nothing). Prints its own one-line
 * error; returns an exit code. */
int synth_run(const synth_opts *o);

#endif
