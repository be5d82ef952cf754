/* Where `make weights` puts the pretrained perceptual networks (smplpix/metrics.h). */
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>

#include "smplpix/metrics.h"

int spx_weights_path(const char *name, char *out, size_t cap) {
  if (!out || !cap) return -1;
  out[0] = 0;
  const char *d = getenv("SPX_CACHE_DIR"), *home = getenv("HOME");
  int n;
  if (d && *d) n = snprintf(out, cap, "%s/weights/%s", d, name);
  else if (home && *home) n = snprintf(out, cap, "%s/.cache/smplpix/weights/%s", home, name);
  else return -1;
  if (n < 0 || (size_t)n >= cap) {
    out[0] = 0;
    return -1;
  }
  struct stat sb;
  return stat(out, &sb) == 0 ? 1 : 0;
}
