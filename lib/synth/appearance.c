/* Appearance of a synthetic subject: random look (skin, hair, clothing, prints), the region of a
 * surface point (part map + skinning chains + rest position), its colour and its displacement;
 * the generator's RNG (smplpix/synth.h) that draws the look. */
#include <math.h>
#include <string.h>

#include "core/internal.h"
#include "synth_internal.h"

uint64_t spx_synth_rng_next(spx_synth_rng *r) { return spx_splitmix64(&r->s); }
double spx_synth_rng_uniform(spx_synth_rng *r, double lo, double hi) {
  return lo + (hi - lo) * ((double)(spx_synth_rng_next(r) >> 11) * 0x1.0p-53);
}
double spx_synth_rng_normal(spx_synth_rng *r) {
  double u1 = spx_synth_rng_uniform(r, 0, 1), u2 = spx_synth_rng_uniform(r, 0, 1);
  return sqrt(-2.0 * log(1.0 - u1)) * cos(6.283185307179586 * u2);
}

uint64_t syn_hash(uint64_t a, uint64_t b) {
  uint64_t z = a * 0x9E3779B97F4A7C15ULL ^ (b + 0x632BE59BD9B4E019ULL + (a << 6) + (a >> 2));
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

static spx_status joint_pos(spx_ctx *ctx, const spx_body_model *m, const char *name, double out[3]) {
  int32_t k = spx_body_joint_index(m, name);
  if (k < 0)
    return spx_fail(ctx, SPX_E_ARG, "body model has no joint named %s (synth needs the CMU rig of the default body)",
                    name);
  for (int c = 0; c < 3; c++) out[c] = m->J_template[k * 3 + c];
  return SPX_OK;
}

spx_status syn_skel_init(spx_ctx *ctx, const spx_body_model *m, syn_skel *sk) {
  spx_status st;
  memset(sk, 0, sizeof *sk);
  if ((st = joint_pos(ctx, m, "Head", sk->head)) || (st = joint_pos(ctx, m, "Neck", sk->neck)) ||
      (st = joint_pos(ctx, m, "Hips", sk->hips)) || (st = joint_pos(ctx, m, "LeftUpLeg", sk->upleg)) ||
      (st = joint_pos(ctx, m, "LeftLeg", sk->knee)) || (st = joint_pos(ctx, m, "LeftFoot", sk->ankle)) ||
      (st = joint_pos(ctx, m, "LeftArm", sk->arm)) || (st = joint_pos(ctx, m, "LeftHand", sk->hand)))
    return st;
  sk->floor_y = INFINITY;
  sk->top_y = -INFINITY;
  for (int32_t i = 0; i < m->nv; i++) {
    sk->floor_y = fmin(sk->floor_y, m->v_template[i * 3 + 1]);
    sk->top_y = fmax(sk->top_y, m->v_template[i * 3 + 1]);
  }
  return SPX_OK;
}

static int chain_of(const char *name) {
  if (strstr(name, "Neck") || strstr(name, "Head")) return SYN_NECK;
  if (strstr(name, "Arm") || strstr(name, "Hand") || strstr(name, "Thumb") || strstr(name, "Finger")) return SYN_ARM;
  if (strstr(name, "Leg") || strstr(name, "Foot") || strstr(name, "Toe") || strstr(name, "HipJoint")) return SYN_LEG;
  return SYN_TORSO;
}

spx_status syn_chain_weights(spx_ctx *ctx, const spx_body_model *m, float *chain) {
  if (!m->joint_names) return spx_fail(ctx, SPX_E_ARG, "body model has no joint_names (synth needs them)");
  int cj[1024];
  if (m->nj > 1024) return spx_fail(ctx, SPX_E_ARG, "body model has %d joints, more than synth supports", m->nj);
  for (int32_t k = 0; k < m->nj; k++) cj[k] = chain_of(m->joint_names[k]);
  for (int32_t i = 0; i < m->nv; i++) {
    float *c = chain + (size_t)i * SYN_NCHAINS;
    for (int q = 0; q < SYN_NCHAINS; q++) c[q] = 0;
    for (int32_t k = 0; k < m->nj; k++) c[cj[k]] += m->weights[(size_t)i * m->nj + k];
  }
  return SPX_OK;
}

/* Colours of body_parts_segmentation.yaml. */
static const struct {
  unsigned char rgb[3];
  int part;
} PART_COLORS[] = {
    {{0, 0, 0}, SPX_PART_BODY},         {{90, 86, 255}, SPX_PART_HEAD},     {{255, 29, 35}, SPX_PART_HAND},
    {{7, 255, 0}, SPX_PART_HAND},       {{255, 101, 0}, SPX_PART_EYE},      {{16, 231, 186}, SPX_PART_EYE},
    {{24, 170, 109}, SPX_PART_EYE},     {{16, 115, 231}, SPX_PART_EYE},     {{253, 249, 16}, SPX_PART_EYE},
    {{249, 108, 136}, SPX_PART_EYE},    {{112, 172, 255}, SPX_PART_MOUTH},  {{254, 251, 251}, SPX_PART_FOOT},
    {{255, 0, 245}, SPX_PART_FOOT},     {{206, 153, 167}, SPX_PART_MOUTH},
};

int syn_part_of_rgb(double r, double g, double b) {
  int best = SPX_PART_BODY;
  double bd = 40.0 * 40.0 * 3; /* colours further than this from every entry count as body */
  for (size_t i = 0; i < sizeof PART_COLORS / sizeof PART_COLORS[0]; i++) {
    double dr = r * 255 - PART_COLORS[i].rgb[0], dg = g * 255 - PART_COLORS[i].rgb[1],
           db = b * 255 - PART_COLORS[i].rgb[2];
    double d = dr * dr + dg * dg + db * db;
    if (d < bd) {
      bd = d;
      best = PART_COLORS[i].part;
    }
  }
  return best;
}

int syn_part_at(const spx_image *pm, double u, double v) {
  int x = (int)floor(u * pm->width), y = (int)floor((1.0 - v) * pm->height);
  x = x < 0 ? 0 : x >= pm->width ? pm->width - 1 : x;
  y = y < 0 ? 0 : y >= pm->height ? pm->height - 1 : y;
  const float *p = pm->data + ((size_t)y * pm->width + x) * pm->channels;
  if (pm->channels < 3) return syn_part_of_rgb(p[0], p[0], p[0]);
  return syn_part_of_rgb(p[0], p[1], p[2]);
}

static void set3(double d[3], double a, double b, double c) {
  d[0] = a;
  d[1] = b;
  d[2] = c;
}
static void lerp_palette(const double (*pal)[3], int n, double t, double out[3]) {
  double x = t * (n - 1);
  int i = (int)floor(x);
  if (i >= n - 1) i = n - 2;
  if (i < 0) i = 0;
  double f = x - i;
  for (int c = 0; c < 3; c++) out[c] = pal[i][c] * (1 - f) + pal[i + 1][c] * f;
}

static const double SKIN[][3] = {{0.96, 0.82, 0.72}, {0.88, 0.69, 0.56}, {0.77, 0.58, 0.43},
                                 {0.60, 0.42, 0.29}, {0.42, 0.28, 0.18}, {0.28, 0.18, 0.12}};
static const double HAIR[][3] = {{0.05, 0.04, 0.04}, {0.20, 0.12, 0.07}, {0.38, 0.24, 0.13},
                                 {0.80, 0.65, 0.38}, {0.55, 0.22, 0.09}, {0.62, 0.62, 0.60}};
static const double CLOTH[][3] = {{0.85, 0.10, 0.10}, {0.10, 0.25, 0.70}, {0.08, 0.45, 0.20}, {0.95, 0.80, 0.15},
                                  {0.95, 0.95, 0.93}, {0.08, 0.08, 0.09}, {0.45, 0.45, 0.48}, {0.55, 0.10, 0.45},
                                  {0.95, 0.50, 0.10}, {0.10, 0.60, 0.65}, {0.40, 0.25, 0.12}, {0.70, 0.85, 0.95},
                                  {0.20, 0.22, 0.40}, {0.85, 0.55, 0.65}};
#define NCLOTH ((int)(sizeof CLOTH / sizeof CLOTH[0]))

static void cloth_color(spx_synth_rng *r, double out[3]) {
  int i = (int)(spx_synth_rng_next(r) % NCLOTH);
  for (int c = 0; c < 3; c++) out[c] = fmin(1.0, fmax(0.0, CLOTH[i][c] * spx_synth_rng_uniform(r, 0.85, 1.1)));
}

static void garment_init(spx_synth_rng *r, syn_garment *g) {
  cloth_color(r, g->base);
  do cloth_color(r, g->second);
  while (fabs(g->second[0] - g->base[0]) + fabs(g->second[1] - g->base[1]) + fabs(g->second[2] - g->base[2]) < 0.4);
  g->pattern = (int)(spx_synth_rng_next(r) % SYN_NPATTERNS);
  g->period = spx_synth_rng_uniform(r, 0.015, 0.05); /* 2..7 pixels at 410x308 from ~3 m */
  g->duty = spx_synth_rng_uniform(r, 0.3, 0.5);
  if (g->pattern == SYN_PINSTRIPES) {
    g->period = spx_synth_rng_uniform(r, 0.015, 0.03);
    g->duty = spx_synth_rng_uniform(r, 0.2, 0.35);
  }
}

static const char *WORDS[] = {"SMPLPIX", "HELLO", "SCAN 42", "RUN!", "ZEBRA", "NOVA", "PIXEL", "WAVE 7", "ORBIT", "KYOTO"};

void syn_look_init(spx_synth_rng *r, const syn_skel *sk, syn_look *lk) {
  memset(lk, 0, sizeof *lk);
  lerp_palette(SKIN, 6, spx_synth_rng_uniform(r, 0, 1), lk->skin);
  lerp_palette(HAIR, 6, spx_synth_rng_uniform(r, 0, 1), lk->hair);
  set3(lk->eye, 0.12, 0.08, 0.06);
  set3(lk->mouth, lk->skin[0] * 0.7, lk->skin[1] * 0.45, lk->skin[2] * 0.45);
  cloth_color(r, lk->shoe);
  double s = spx_synth_rng_uniform(r, 0, 1) < 0.5 ? 0.95 : 0.12;
  set3(lk->sole, s, s, s);
  set3(lk->belt, 0.25, 0.15, 0.08);
  garment_init(r, &lk->shirt);
  garment_init(r, &lk->pants);
  lk->bald = spx_synth_rng_uniform(r, 0, 1) < 0.1;
  double head_h = sk->top_y - sk->head[1];
  lk->hair_front_y = sk->head[1] + head_h * spx_synth_rng_uniform(r, 0.45, 0.6);
  int long_hair = spx_synth_rng_uniform(r, 0, 1) < 0.35;
  lk->hair_back_y = long_hair ? sk->neck[1] - spx_synth_rng_uniform(r, 0.0, 0.08)
                              : sk->head[1] - spx_synth_rng_uniform(r, 0.0, 0.04);
  lk->hair_volume = spx_synth_rng_uniform(r, 0.008, 0.035);
  lk->sleeve = spx_synth_rng_uniform(r, 0, 1) < 0.5 ? spx_synth_rng_uniform(r, 0.2, 0.4) : spx_synth_rng_uniform(r, 0.85, 1.0);
  lk->neck_y = sk->neck[1] - spx_synth_rng_uniform(r, 0.02, 0.05);
  lk->vneck = spx_synth_rng_uniform(r, 0, 1) < 0.4 ? spx_synth_rng_uniform(r, 0.04, 0.1) : 0.0;
  lk->waist_y = sk->hips[1] + spx_synth_rng_uniform(r, 0.0, 0.08);
  lk->belt_w = spx_synth_rng_uniform(r, 0, 1) < 0.5 ? spx_synth_rng_uniform(r, 0.025, 0.04) : 0.0;
  double u = spx_synth_rng_uniform(r, 0, 1);
  lk->hem_y = u < 0.3 ? sk->knee[1] + spx_synth_rng_uniform(r, 0.05, 0.2)  /* shorts */
                      : sk->ankle[1] + spx_synth_rng_uniform(r, 0.02, 0.12); /* trousers */
  lk->print = (int)(spx_synth_rng_next(r) % 3);
  snprintf(lk->text, sizeof lk->text, "%s", WORDS[spx_synth_rng_next(r) % (sizeof WORDS / sizeof WORDS[0])]);
  lk->text_cell = spx_synth_rng_uniform(r, 0.006, 0.011);
  double tw = 6.0 * (double)strlen(lk->text) - 1; /* keep the word on the front of the chest */
  if (tw * lk->text_cell > 0.24) lk->text_cell = 0.24 / tw;
  lk->text_y = sk->neck[1] - spx_synth_rng_uniform(r, 0.1, 0.16);
  lk->logo_r = spx_synth_rng_uniform(r, 0.035, 0.06);
  lk->logo_x = spx_synth_rng_uniform(r, -0.08, 0.08);
  lk->logo_y = sk->neck[1] - spx_synth_rng_uniform(r, 0.12, 0.2);
  lk->loose_shirt = spx_synth_rng_uniform(r, 0.008, 0.025);
  lk->loose_pants = spx_synth_rng_uniform(r, 0.005, 0.015);
  lk->fold_amp = spx_synth_rng_uniform(r, 0.002, 0.006);
  lk->fold_len = spx_synth_rng_uniform(r, 0.04, 0.09);
  lk->fold_phase = spx_synth_rng_uniform(r, 0, 6.283185307179586);
  lk->shoe_thick = spx_synth_rng_uniform(r, 0.004, 0.01);
  lk->collar_r = spx_synth_rng_uniform(r, 0.075, 0.11);
  lk->flare = spx_synth_rng_uniform(r, 0, 1) < 0.3 ? spx_synth_rng_uniform(r, 0.02, 0.05) : 0.0;
}

static int dominant(const syn_point *pt) {
  int c = 0;
  for (int q = 1; q < SYN_NCHAINS; q++)
    if (pt->chain[q] > pt->chain[c]) c = q;
  return c;
}

/* Position along the (mirrored) shoulder→wrist segment, 0 at the shoulder, 1 at the wrist. */
static double arm_param(const syn_skel *sk, const double p[3]) {
  double d[3] = {sk->hand[0] - sk->arm[0], sk->hand[1] - sk->arm[1], sk->hand[2] - sk->arm[2]};
  double q[3] = {fabs(p[0]) - sk->arm[0], p[1] - sk->arm[1], p[2] - sk->arm[2]};
  double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  return dd > 0 ? (q[0] * d[0] + q[1] * d[1] + q[2] * d[2]) / dd : 0;
}

static int is_hair(const syn_look *lk, const syn_skel *sk, const double p[3]) {
  if (lk->bald) return 0;
  double qx = p[0] - sk->head[0], qz = p[2] - sk->head[2];
  double rr = sqrt(qx * qx + qz * qz), fr = rr > 0 ? qz / rr : 0;
  if (p[1] > lk->hair_front_y + 0.03 * fmax(0.0, fr)) return 1;
  return fr < 0.15 && p[1] > lk->hair_back_y;
}

int syn_region(const syn_look *lk, const syn_skel *sk, const syn_point *pt) {
  const double *p = pt->p;
  switch (pt->part) {
  case SPX_PART_EYE: return SYN_EYE;
  case SPX_PART_MOUTH: return SYN_MOUTH;
  case SPX_PART_HAND: return SYN_SKIN;
  case SPX_PART_FOOT: return p[1] < sk->floor_y + 0.02 ? SYN_SOLE : SYN_SHOE;
  case SPX_PART_HEAD: return is_hair(lk, sk, p) ? SYN_HAIR : SYN_SKIN;
  default: break;
  }
  int c = dominant(pt);
  if (c == SYN_NECK || c == SYN_TORSO) {
    if (is_hair(lk, sk, p) && p[2] < sk->neck[2] && fabs(p[0]) < 0.1) return SYN_HAIR;
    if (p[1] > lk->waist_y) {
      /* the neckline: a collar cylinder around the neck cut at neck_y (lower at the front with a V) */
      double top = lk->neck_y - (p[2] > sk->neck[2] ? lk->vneck * fmax(0.0, 1.0 - fabs(p[0]) / 0.08) : 0.0);
      double rx = p[0] - sk->neck[0], rz = p[2] - sk->neck[2];
      int in_collar = rx * rx + rz * rz < lk->collar_r * lk->collar_r;
      return (in_collar && p[1] > top) || p[1] > sk->neck[1] + 0.03 ? SYN_SKIN : SYN_SHIRT;
    }
    return p[1] > lk->waist_y - lk->belt_w ? SYN_BELT : SYN_PANTS;
  }
  if (c == SYN_ARM) return arm_param(sk, p) < lk->sleeve ? SYN_SHIRT : SYN_SKIN;
  /* leg */
  if (p[1] < sk->ankle[1] + 0.04) return SYN_SHOE;
  if (p[1] > lk->waist_y) return SYN_SHIRT;
  if (p[1] > lk->waist_y - lk->belt_w) return SYN_BELT;
  return p[1] > lk->hem_y ? SYN_PANTS : SYN_SKIN;
}

/* Surface coordinates for patterns: `along` a limb or up the torso, `around` it (metres). */
static void surface_coords(const syn_skel *sk, const syn_point *pt, double *along, double *around) {
  const double *p = pt->p;
  int c = dominant(pt);
  if (c == SYN_ARM) {
    double t = arm_param(sk, p);
    double len = sqrt((sk->hand[0] - sk->arm[0]) * (sk->hand[0] - sk->arm[0]) +
                      (sk->hand[1] - sk->arm[1]) * (sk->hand[1] - sk->arm[1]));
    double cy = sk->arm[1] + t * (sk->hand[1] - sk->arm[1]), cz = sk->arm[2] + t * (sk->hand[2] - sk->arm[2]);
    *along = t * len;
    *around = atan2(p[1] - cy, p[2] - cz) * 0.045;
  } else if (c == SYN_LEG && p[1] < sk->upleg[1]) {
    double cx = p[0] >= 0 ? sk->upleg[0] : -sk->upleg[0];
    *along = p[1];
    *around = atan2(p[0] - cx, p[2] - sk->upleg[2]) * 0.07;
  } else {
    *along = p[1];
    *around = atan2(p[0], p[2] - sk->hips[2]) * 0.14;
  }
}

static double frac(double x) { return x - floor(x); }

static void pattern(const syn_garment *g, double along, double around, double rgb[3]) {
  double mix = 0;
  switch (g->pattern) {
  case SYN_HSTRIPES: mix = frac(along / g->period) < g->duty; break;
  case SYN_VSTRIPES:
  case SYN_PINSTRIPES: mix = frac(around / g->period) < g->duty; break;
  case SYN_CHECKS: mix = 0.5 * ((frac(along / g->period) < g->duty) + (frac(around / g->period) < g->duty)); break;
  case SYN_DOTS: {
    double a = frac(along / g->period) - 0.5, b = frac(around / g->period) - 0.5;
    mix = sqrt(a * a + b * b) < 0.5 * g->duty;
    break;
  }
  default: break;
  }
  for (int c = 0; c < 3; c++) rgb[c] = g->base[c] * (1 - mix) + g->second[c] * mix;
}

/* 1 where the chest print (text or logo) covers a shirt point. */
static int print_at(const syn_look *lk, const syn_skel *sk, const syn_point *pt) {
  const double *p = pt->p;
  if (p[2] < sk->hips[2] + 0.02 || dominant(pt) == SYN_ARM) return 0; /* front only */
  if (lk->print == SYN_PRINT_TEXT) {
    int n = (int)strlen(lk->text);
    double w = (6.0 * n - 1) * lk->text_cell;
    double fx = (p[0] + 0.5 * w) / lk->text_cell, fy = (lk->text_y - p[1]) / lk->text_cell;
    if (fx < 0 || fy < 0 || fy >= 7 || fx >= 6.0 * n) return 0;
    int gx = (int)fx, gy = (int)fy;
    return syn_glyph_pixel(lk->text[gx / 6], gx % 6, gy);
  }
  if (lk->print == SYN_PRINT_LOGO) {
    double dx = p[0] - lk->logo_x, dy = p[1] - lk->logo_y, r = sqrt(dx * dx + dy * dy);
    if (r > lk->logo_r) return 0;
    if (r > 0.8 * lk->logo_r) return 1;                        /* ring */
    if (r < 0.6 * lk->logo_r) return frac((dx + dy) / (0.25 * lk->logo_r)) < 0.5; /* hatched disc */
    return 0;
  }
  return 0;
}

void syn_color(const syn_look *lk, const syn_skel *sk, const syn_point *pt, int region, double grain, double rgb[3]) {
  double along, around, g = 1.0;
  switch (region) {
  case SYN_HAIR: {
    surface_coords(sk, pt, &along, &around);
    uint64_t strand = syn_hash((uint64_t)(int64_t)floor(around / 0.003) + 7, 11);
    double s = 0.75 + 0.5 * (double)(strand >> 11) * 0x1.0p-53;
    for (int c = 0; c < 3; c++) rgb[c] = lk->hair[c] * s + 0.03;
    g = 0.95 + 0.1 * grain;
    break;
  }
  case SYN_EYE: memcpy(rgb, lk->eye, sizeof lk->eye); break;
  case SYN_MOUTH: memcpy(rgb, lk->mouth, sizeof lk->mouth); break;
  case SYN_SHIRT:
  case SYN_PANTS: {
    const syn_garment *gm = region == SYN_SHIRT ? &lk->shirt : &lk->pants;
    surface_coords(sk, pt, &along, &around);
    pattern(gm, along, around, rgb);
    if (region == SYN_SHIRT && print_at(lk, sk, pt)) {
      double lum = 0.3 * gm->base[0] + 0.6 * gm->base[1] + 0.1 * gm->base[2];
      double v = lum > 0.5 ? 0.05 : 0.97;
      set3(rgb, v, v, v);
    }
    g = 0.93 + 0.14 * grain;
    break;
  }
  case SYN_BELT: memcpy(rgb, lk->belt, sizeof lk->belt); break;
  case SYN_SHOE: memcpy(rgb, lk->shoe, sizeof lk->shoe); g = 0.95 + 0.1 * grain; break;
  case SYN_SOLE: memcpy(rgb, lk->sole, sizeof lk->sole); break;
  default: memcpy(rgb, lk->skin, sizeof lk->skin); g = 0.97 + 0.06 * grain; break;
  }
  for (int c = 0; c < 3; c++) rgb[c] = fmin(1.0, fmax(0.0, rgb[c] * g));
}

double syn_displace(const syn_look *lk, const syn_skel *sk, const syn_point *pt, int region) {
  double along, around;
  switch (region) {
  case SYN_SHIRT:
  case SYN_PANTS:
  case SYN_BELT: {
    surface_coords(sk, pt, &along, &around);
    double fold = lk->fold_amp * sin(6.283185307179586 * along / lk->fold_len + lk->fold_phase + 2.0 * sin(around * 40.0));
    if (region == SYN_SHIRT) {
      double taper = fmin(1.0, fmax(0.3, (lk->neck_y - pt->p[1]) / 0.08)); /* close at the collar */
      return taper * (lk->loose_shirt + fold);
    }
    double below_knee = (sk->knee[1] + 0.05 - pt->p[1]) / (sk->knee[1] + 0.05 - sk->ankle[1]);
    double flare = lk->flare * fmin(1.0, fmax(0.0, below_knee));
    return lk->loose_pants + flare + 0.7 * fold + (region == SYN_BELT ? 0.004 : 0.0);
  }
  case SYN_HAIR: return lk->hair_volume * fmin(1.0, fmax(0.25, (pt->p[1] - lk->hair_back_y) / 0.04));
  case SYN_SHOE:
  case SYN_SOLE: return lk->shoe_thick;
  default: return 0.0;
  }
}
