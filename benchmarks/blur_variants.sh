#!/usr/bin/env bash
# What blurs the SMPLpix rendering: one training recipe changed at a time, every variant scored on
# the same unseen test views (subjects and a stretch of the motion no network saw) with PSNR,
# LPIPS and detail (`smplpix eval`), full image and inside the mask, and its training CPU time.
# The table goes to WORK/variants/VARIANTS.md (benchmarks/RESULTS.md holds the committed one).
#
# usage: benchmarks/blur_variants.sh WORK [VARIANT ...]
#   WORK: a `make table1` work folder whose data are made (synth, registrations, the inputs at 13k
#         and 53k vertices, the ground truth, masks and per-vertex rasters of the test views);
#         its training stages are not needed.
#   VARIANTS (default: all, in this order):
#     base      13,380 vertices: BV_L1 steps of l1 (lr 2e-3), then BV_VGG of vgg16 (lr 2e-4)
#     vgg3x     base, its vgg16 stage continued to 3 x BV_VGG steps (--resume)
#     vggonly   vgg16 from the start (lr 1e-3), as many steps as cost base's CPU time (BV_VGGONLY)
#     w32       base at width 32
#     cosine    base with --lr-decay cosine in both stages
#     bnrecal   base's network, its batch-norm running statistics estimated again at its final
#               weights (bench_bn_stats recalibrate, over the training inputs)
#     bnbatch   base's network rendering with each test image's own batch statistics
#     v53k      base on the 53,514-vertex inputs
#     v53k3x    v53k, its vgg16 stage continued to 3 x BV_VGG steps (--resume)
#     oldframe  base on the earlier framing (landscape 256x192, the subject at 0.72..0.9 of the
#               height): BV_OLD_SYNTH = a synth output of the same seed made by the earlier
#               `smplpix synth` (same subjects, poses, view directions and light; only the cameras
#               differ); its inputs are WORK's reposed registrations projected through its cameras
# Environment: BV_BUILD (default build), BV_L1 (1000), BV_VGG (200), BV_VGGONLY (450), BV_WIDTH (16),
# BV_BATCH (4), BV_SEED (1), BV_OLD_SYNTH. Resumable: a finished step leaves WORK/variants/done/*;
# a stopped training continues from its last checkpoint. Runs every command under nice -n 10.
set -eu
set -o pipefail
die() { echo "blur_variants: error: $*" >&2; exit 1; }
[ $# -ge 1 ] || die "usage: blur_variants.sh WORK [VARIANT ...]"
work=$(cd "$1" && pwd) || die "$1: no such folder"
shift
root=$(cd "$(dirname "$0")/.." && pwd)
build=${BV_BUILD:-$root/build}
tool=$build/smplpix bn=$build/benchmarks/bench_bn_stats
L1=${BV_L1:-1000} VGG=${BV_VGG:-200} VGGONLY=${BV_VGGONLY:-450} WIDTH=${BV_WIDTH:-16} BATCH=${BV_BATCH:-4}
SEED=${BV_SEED:-1}
for f in "$tool" "$bn"; do [ -x "$f" ] || die "$f: not built"; done
for d in data13k data53k methods/gt methods/mask methods/pervertex13k; do
  [ -d "$work/$d" ] || die "$work/$d: missing (run make table1 into $work first)"
done
out=$work/variants
mkdir -p "$out/done"
log=$out/log.txt
n() { nice -n 10 "$@"; }
say() { printf 'blur_variants [%s] %s\n' "$(date -u +%H:%M:%S)" "$*" | tee -a "$log"; }

# cpu NAME CMD...: run CMD, adding its CPU seconds (user + system, children included) to NAME.cpu
cpu() {
  local name=$1 t0 t1
  shift
  t0=$(awk '{print $14 + $15 + $16 + $17}' /proc/$$/stat)
  "$@" >>"$log" 2>&1 || die "$*: $(tail -n 1 "$log")"
  t1=$(awk '{print $14 + $15 + $16 + $17}' /proc/$$/stat)
  awk -v a="$t0" -v b="$t1" -v hz="$(getconf CLK_TCK)" -v f="$out/$name.cpu" \
    'BEGIN { p = 0; if ((getline v < f) > 0) p = v; close(f); printf "%.1f\n", p + (b - a) / hz > f }'
}
# train NAME DATA STEPS [ARGS...]: smplpix train to $out/NAME.safetensors (continued when stopped)
train() {
  local name=$1 data=$2 steps=$3
  shift 3
  [ -f "$out/done/train.$name" ] && return 0
  say "train $name: $steps steps $*"
  if [ -f "$out/$name.safetensors" ]; then
    cpu "$name" n "$tool" train --data "$data" --out "$out/$name.safetensors" --resume --steps "$steps" --log-every 50
  else
    cpu "$name" n "$tool" train --data "$data" --out "$out/$name.safetensors" --batch "$BATCH" --steps "$steps" \
      --seed "$SEED" --log-every 50 --save-every 100 "$@"
  fi
  : >"$out/done/train.$name"
}
# score NAME DATA GT MASK [CHECKPOINT]: render DATA/test through the network, eval against GT / MASK
score() {
  local name=$1 data=$2 gt=$3 mask=$4 ck=${5:-$out/$1.safetensors} f
  [ -f "$out/done/eval.$name" ] && return 0
  rm -rf "$out/r.$name" && mkdir -p "$out/r.$name"
  for f in "$data/test/input/"*.exr; do
    n "$tool" render --checkpoint "$ck" --input "$f" --out "$out/r.$name/$(basename "$f" .exr).png" --quiet >>"$log" 2>&1 ||
      die "render $name: $(tail -n 1 "$log")"
  done
  scoredir "$name" "$out/r.$name" "$gt" "$mask"
}
scoredir() { # scoredir NAME PRED GT MASK
  n "$tool" eval --pred "$2" --target "$3" --mask "$4" --json "$out/eval.$1.json" >>"$log" 2>&1 || die "eval $1: $(tail -n 1 "$log")"
  : >"$out/done/eval.$1"
}
# stage1+2 NAME DATA [TRAIN ARGS...]: the base recipe (l1 then vgg16 from it), both stages scored
two_stage() {
  local name=$1 data=$2 gt=${GT:-$work/methods/gt} mask=${MASK:-$work/methods/mask}
  shift 2
  train "$name.l1" "$data" "$L1" --loss l1 --lr 2e-3 --width "$WIDTH" "$@"
  score "$name.l1" "$data" "$gt" "$mask"
  train "$name.vgg" "$data" "$VGG" --loss vgg16 --lr 2e-4 --init "$out/$name.l1.safetensors" "$@"
  score "$name.vgg" "$data" "$gt" "$mask"
}

v_base() { two_stage base "$work/data13k"; }
# vgg_longer NAME FROM DATA: FROM's vgg16 stage continued to 3 x VGG steps (--resume), as NAME
vgg_longer() {
  local name=$1 from=$2 data=$3
  [ -f "$out/$name.safetensors" ] || [ -f "$out/done/train.$name" ] || cp "$out/$from.safetensors" "$out/$name.safetensors"
  [ -f "$out/$name.cpu" ] || cpu_of "$from" >"$out/$name.cpu"
  train "$name" "$data" $((3 * VGG))
  score "$name" "$data" "$work/methods/gt" "$work/methods/mask"
}
v_vgg3x() { v_base; vgg_longer vgg3x base.vgg "$work/data13k"; }
v_vggonly() {
  train vggonly "$work/data13k" "$VGGONLY" --loss vgg16 --lr 1e-3 --width "$WIDTH"
  score vggonly "$work/data13k" "$work/methods/gt" "$work/methods/mask"
}
v_w32() { WIDTH=32 two_stage w32 "$work/data13k"; }
v_cosine() { two_stage cosine "$work/data13k" --lr-decay cosine; }
v_bnrecal() {
  v_base
  [ -f "$out/done/train.bnrecal" ] || {
    cpu bnrecal n "$bn" recalibrate --checkpoint "$out/base.vgg.safetensors" --inputs "$work/data13k/train/input" \
      --out "$out/bnrecal.safetensors" --passes 2 --batch "$BATCH"
    : >"$out/done/train.bnrecal"
  }
  score bnrecal "$work/data13k" "$work/methods/gt" "$work/methods/mask"
}
v_bnbatch() {
  v_base
  [ -f "$out/done/eval.bnbatch" ] && return 0
  rm -rf "$out/r.bnbatch" && mkdir -p "$out/r.bnbatch"
  cpu bnbatch n "$bn" render --checkpoint "$out/base.vgg.safetensors" --inputs "$work/data13k/test/input" \
    --out-dir "$out/r.bnbatch" --batch 1
  scoredir bnbatch "$out/r.bnbatch" "$work/methods/gt" "$work/methods/mask"
}
v_v53k() { two_stage v53k "$work/data53k"; }
v_v53k3x() { v_v53k; vgg_longer v53k3x v53k.vgg "$work/data53k"; }

# The earlier framing: WORK's reposed registrations through the old synth output's cameras, the
# same splits; its own ground truth, masks and per-vertex raster.
old_data() {
  local old=$1 d=$out/data-old split f name subj view ext
  [ -f "$out/done/data-old" ] && return 0
  say "data-old: $work's reposed registrations through the cameras of $old"
  rm -rf "$d" && mkdir -p "$d/methods/gt" "$d/methods/mask" "$d/methods/pervertex13k"
  for split in train validation test; do
    mkdir -p "$d/$split/input" "$d/$split/output"
    for f in "$work/data13k/$split/input/"*.exr; do
      name=$(basename "$f" .exr) subj=${name%%_*} view=${name#*_}
      [ -f "$old/$subj/cameras/$view.json" ] || die "$old/$subj/cameras/$view.json: missing (another seed or size?)"
      n "$tool" project --mesh "$work/subjects/$subj/$name.13k.obj" --camera "$old/$subj/cameras/$view.json" \
        --out "$d/$split/input/$name.exr" --color mesh --quiet >>"$log" 2>&1 || die "project $name: $(tail -n 1 "$log")"
      cp "$old/$subj/images/$view.png" "$d/$split/output/$name.png"
      if [ $split = test ]; then
        cp "$old/$subj/images/$view.png" "$d/methods/gt/$name.png"
        cp "$old/$subj/masks/$view.png" "$d/methods/mask/$name.png"
        n "$tool" raster --mesh "$work/subjects/$subj/$name.13k.obj" --camera "$old/$subj/cameras/$view.json" \
          --out "$d/methods/pervertex13k/$name.png" --color mesh --aa 2 --quiet >>"$log" 2>&1 || die "raster $name"
      fi
    done
  done
  : >"$out/done/data-old"
}
v_oldframe() {
  [ -n "${BV_OLD_SYNTH:-}" ] || { say "oldframe: skipped (no BV_OLD_SYNTH)"; return 0; }
  old_data "$BV_OLD_SYNTH"
  [ -f "$out/done/eval.oldframe.pervertex13k" ] ||
    scoredir oldframe.pervertex13k "$out/data-old/methods/pervertex13k" "$out/data-old/methods/gt" "$out/data-old/methods/mask"
  GT=$out/data-old/methods/gt MASK=$out/data-old/methods/mask two_stage oldframe "$out/data-old"
}

# reference rows: the rasterizers on the same (new framing) test views
refs() {
  local m
  for m in pervertex13k pervertex53k textured13k; do
    [ -f "$out/done/eval.$m" ] || [ ! -d "$work/methods/$m" ] || scoredir "$m" "$work/methods/$m" "$work/methods/gt" "$work/methods/mask"
  done
}

# cpu_of KEY: the training CPU seconds behind a scored network (a second stage: both stages)
cpu_of() {
  local f=$out/$1.cpu first=
  case $1 in *.vgg) first=$out/${1%.vgg}.l1.cpu ;; bnrecal) first=BASE ;; bnbatch) cpu_of base.vgg; return ;; esac
  [ -f "$f" ] || { echo "—"; return; }
  if [ "$first" = BASE ]; then
    awk -v a="$(cpu_of base.vgg)" -v b="$(cat "$f")" 'BEGIN { printf "%.1f\n", a + b }'
  elif [ -n "$first" ] && [ -f "$first" ]; then
    awk -v a="$(cat "$first")" -v b="$(cat "$f")" 'BEGIN { printf "%.1f\n", a + b }'
  else cat "$f"; fi
}

report() {
  local md=$out/VARIANTS.md k
  {
    echo "| variant | PSNR full | LPIPS full | detail full | PSNR mask | LPIPS mask | detail mask | training CPU (s) |"
    echo "|---|---|---|---|---|---|---|---|"
    for k in pervertex13k pervertex53k textured13k base.l1 base.vgg vgg3x vggonly w32.l1 w32.vgg cosine.l1 cosine.vgg \
      bnrecal bnbatch v53k.l1 v53k.vgg v53k3x oldframe.pervertex13k oldframe.l1 oldframe.vgg; do
      [ -f "$out/eval.$k.json" ] || continue
      jq -r --arg k "$k" --arg c "$(cpu_of "$k")" '
        def r(x): if x == null then "—" else (x * 1000 | round) / 1000 | tostring end;
        "| \($k) | \(r(.psnr)) | \(r(.lpips)) | \(r(.detail_full)) | \(r(.psnr_masked)) | \(r(.lpips_masked)) | \(r(.detail)) | \($c) |"' \
        "$out/eval.$k.json"
    done
  } >"$md.tmp" && mv "$md.tmp" "$md"
  say "wrote $md"
}

[ $# -gt 0 ] || set -- base vgg3x vggonly w32 cosine bnrecal bnbatch v53k v53k3x oldframe
refs
for v in "$@"; do
  type "v_$v" >/dev/null 2>&1 || die "unknown variant $v"
  "v_$v"
  report
done
