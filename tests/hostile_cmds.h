/* The hostile suite's table of every command (tests/test_hostile_options.c,
 * test_hostile_policy.c): a valid command line of each, with its integer, output and input
 * options named, so that a property test drives each option of each command through its cases
 * and a new command added here inherits them all. The files are those of make_scene(1)
 * (hostile.h) plus p.png (the body's part map), m.bvh (a motion clip) and reg.json. */
#ifndef SPX_HOSTILE_CMDS_H
#define SPX_HOSTILE_CMDS_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct cmdline {
  const char *base;     /* a valid command line (files from make_scene) */
  const char *ints;     /* space-separated integer / WxH options of base */
  const char *outs;     /* space-separated output options of base */
  const char *ins;      /* space-separated input options of base */
  int check_base;       /* run base and expect 0 (cheap commands) */
  const char *inside;   /* for a folder output: "OPTION PATH", an input given as a file the command
                           writes into its folder (the input's value is copied there) */
} cmdline;

static const cmdline LINES[] = {
    {"project --mesh quad.obj --camera cam.json --out p.exr --png p.png --npy p.npy --color auto --quiet", "",
     "--out --png --npy", "--mesh --camera", 1, NULL},
    {"raster --mesh quad.obj --camera cam.json --out r.png --aa 2 --cull back --quiet", "--aa", "--out",
     "--mesh --camera", 1, NULL},
    {"dataset --mesh quad.obj --out dsx --orbit 3 --size 32x24 --seed 1 --aa 1 --quiet --force", "--orbit --size --seed --aa",
     "--out", "--mesh", 1, NULL},
    {"render --checkpoint w8.safetensors --mesh quad.obj --camera cam.json --out rr.png --batch 2 --quiet", "--batch",
     "--out", "--checkpoint --mesh --camera", 1, NULL},
    {"train --data ds --out t.safetensors --width 8 --steps 1 --seed 1 --batch 1 --log-every 5 --save-every 9",
     "--width --steps --seed --batch --log-every --save-every", "--out", "--data", 1, NULL},
    {"export --checkpoint w8.safetensors --out e.safetensors --meta a=b", "", "--out", "--checkpoint", 1, NULL},
    {"eval --pred p.png --target p.png --json ev.json --per-image", "", "--json", "--pred --target", 1, NULL},
    {"demo --out dm --frame 3 --seed 2 --zoom 2 --size 32x24 --quiet --checkpoint w8.safetensors",
     "--frame --seed --zoom --size", "--out", "--checkpoint", 0, "--checkpoint dm/demo_smplpix.png"},
    {"synth --subjects 1 --views 1 --seed 1 --size 32x24 --texture-size 256 --out sy --quiet --parts p.png",
     "--subjects --views --seed --size --texture-size", "--out", "--parts", 0, NULL},
    {"tune --quick --repeat 2 --size 32x32 --checkpoint w8.safetensors", "--repeat --size", "", "--checkpoint", 0, NULL},
    {"devices --warmup --peak --device cpu", "", "", "", 0, NULL},
    {"register --scan quad.obj --out reg.ply --params reg.json --threads 2 --units m", "--threads", "--out --params",
     "--scan", 0, NULL},
    {"repose --registration reg.json --bvh m.bvh --frame 2 --subdivide 1 --out v.ply", "--frame --subdivide", "--out",
     "--registration --bvh", 0, NULL},
    {"reshape --registration reg.json --shape 0:+1 --out v.ply --rest", "", "--out", "--registration", 0, NULL},
    {"animate --registration reg.json --bvh m.bvh --camera cam.json --out an.mp4 --fps 10 --frames 0:2 "
     "--checkpoint w8.safetensors", "", "--out", "--registration --bvh --camera --checkpoint", 0,
     "--checkpoint an.mp4/frame_000001.png"},
    {"bake --mesh quad.obj --scan quad.obj --out t.png --size 64 --pad 2", "--size --pad", "--out", "--mesh --scan", 0, NULL},
    {"avatar --scan quad.obj --texture p.png --out av --registration reg.json --poses m.bvh --views 2 --heldout 1 "
     "--size 32x32 --width 8 --steps 1 --seed 1 --quiet", "--views --heldout --size --width --steps --seed", "--out",
     "--scan --texture --registration --poses", 0, "--texture av/report.png"},
};
enum { NLINES = (int)(sizeof LINES / sizeof LINES[0]) };

/* Tokens of s (space-separated) into tok (pointers into buf). */
static inline int split(const char *s, char *buf, size_t cap, char **tok, int max) {
  snprintf(buf, cap, "%s", s);
  int n = 0;
  for (char *t = strtok(buf, " "); t && n < max; t = strtok(NULL, " ")) tok[n++] = t;
  return n;
}

static inline int listed(const char *list, const char *name) {
  char buf[512], *tok[32];
  int n = split(list, buf, sizeof buf, tok, 32);
  for (int i = 0; i < n; i++)
    if (!strcmp(tok[i], name)) return 1;
  return 0;
}

/* value of option name in tok (NULL: a flag or absent). */
static inline const char *value_of(char **tok, int n, const char *name) {
  for (int i = 0; i + 1 < n; i++)
    if (!strcmp(tok[i], name) && strncmp(tok[i + 1], "--", 2)) return tok[i + 1];
  return NULL;
}

/* The command line tok with option `name`'s value replaced by v. */
static inline void with_value(char **tok, int n, const char *name, const char *v, char *out, size_t cap) {
  out[0] = 0;
  for (int i = 0; i < n; i++) {
    const char *t = tok[i];
    if (i > 0 && !strcmp(tok[i - 1], name) && strncmp(t, "--", 2)) t = v;
    strncat(out, t, cap - strlen(out) - 2);
    strncat(out, " ", cap - strlen(out) - 1);
  }
}

#endif
