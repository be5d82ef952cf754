/* Private pieces of the synthetic-subject generator (lib/synth). */
#ifndef SPX_SYNTH_INTERNAL_H
#define SPX_SYNTH_INTERNAL_H

#include "smplpix/synth.h"

/* Surface regions of a subject. */
enum {
  SYN_SKIN = 0, SYN_HAIR, SYN_EYE, SYN_MOUTH, SYN_SHIRT, SYN_PANTS, SYN_BELT, SYN_SHOE, SYN_SOLE, SYN_NREGIONS
};
enum { SYN_SOLID = 0, SYN_HSTRIPES, SYN_VSTRIPES, SYN_PINSTRIPES, SYN_CHECKS, SYN_DOTS, SYN_NPATTERNS };
enum { SYN_PRINT_NONE = 0, SYN_PRINT_TEXT, SYN_PRINT_LOGO };
/* Skinning chains used to split the body part: torso, arm, leg, neck/head. */
enum { SYN_TORSO = 0, SYN_ARM, SYN_LEG, SYN_NECK, SYN_NCHAINS };

typedef struct syn_garment {
  double base[3], second[3];
  int pattern;
  double period; /* metres */
  double duty;   /* fraction of a period in the second colour */
} syn_garment;

/* Landmarks of the zero-shape rest body (from the model's joints). */
typedef struct syn_skel {
  double head[3], neck[3], hips[3], upleg[3], knee[3], ankle[3], arm[3], hand[3];
  double floor_y, top_y;
} syn_skel;

typedef struct syn_look {
  double skin[3], hair[3], eye[3], mouth[3], shoe[3], sole[3], belt[3];
  syn_garment shirt, pants;
  int bald;
  double hair_front_y, hair_back_y, hair_volume; /* hairline heights, volume (m) */
  double sleeve;                 /* fraction of the shoulder→wrist segment covered */
  double neck_y, vneck, collar_r; /* neckline height, extra V depth at the front, collar radius */
  double waist_y, belt_w;        /* shirt / trousers boundary; belt width (0 = none) */
  double hem_y;                  /* trousers end */
  int print;
  char text[12];
  double text_cell, text_y;      /* glyph pixel size (m), baseline height of the top row */
  double logo_r, logo_x, logo_y; /* logo radius, centre on the chest */
  double loose_shirt, loose_pants, fold_amp, fold_len, fold_phase, shoe_thick;
  double flare; /* extra looseness of trousers at the ankle, growing from the knee (0 = straight) */
} syn_look;

/* What the generator knows about a surface point (texel or scan vertex). */
typedef struct syn_point {
  double p[3];              /* zero-shape rest position */
  double chain[SYN_NCHAINS]; /* summed skinning weights per chain */
  int part;                 /* spx_synth_part */
} syn_point;

spx_status syn_skel_init(spx_ctx *ctx, const spx_body_model *m, syn_skel *sk);
void syn_look_init(spx_synth_rng *rng, const syn_skel *sk, syn_look *lk);
int syn_region(const syn_look *lk, const syn_skel *sk, const syn_point *pt);
/* Colour of a region at a point; `grain` is a per-texel hash in [0,1) for fabric noise. */
void syn_color(const syn_look *lk, const syn_skel *sk, const syn_point *pt, int region, double grain, double rgb[3]);
/* Displacement along the normal (metres) of a region at a point. */
double syn_displace(const syn_look *lk, const syn_skel *sk, const syn_point *pt, int region);

/* Per-vertex chain weights (nv*SYN_NCHAINS) from the model's skinning weights and joint names. */
spx_status syn_chain_weights(spx_ctx *ctx, const spx_body_model *m, float *chain);
/* Part label of a part-map pixel colour. */
int syn_part_of_rgb(double r, double g, double b);
/* Part label at uv (nearest pixel of the part map, uv (0,0) = bottom-left). */
int syn_part_at(const spx_image *partmap, double u, double v);

/* Paint the texture (tex_size^2 RGB) in the UV layout of the base model. */
spx_status syn_paint_texture(spx_ctx *ctx, const spx_body_model *m, const spx_image *partmap, const float *chain,
                             const syn_look *lk, const syn_skel *sk, uint64_t seed, int32_t tex_size, float *tex);

/* Built-in 5x7 bitmap font: 1 if pixel (col 0..4, row 0..6, row 0 = top) of glyph c is set.
 * Letters A-Z (either case), digits, space, '-', '!', '.'. Unknown characters are blank. */
int syn_glyph_pixel(char c, int col, int row);

uint64_t syn_hash(uint64_t a, uint64_t b);

#endif
