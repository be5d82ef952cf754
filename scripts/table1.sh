#!/usr/bin/env bash
# make table1: the paper's experiment (Table 1 of SMPLpix, WACV 2021) end to end on synthetic
# scanned people. Stages (each timed, each unit's outputs complete before its done-mark is set):
#   synth     smplpix synth: subjects (scan, cameras, view poses, ground-truth photos)
#   register  per subject: a coloured point cloud sampled from the scan (table1_tool sample),
#             smplpix register (rigid, pose, free), smplpix bake (scan colours -> body UV texture)
#   inputs    per view: smplpix repose (the view's pose from synth.json) at 13,380 vertices and
#             after 1 Loop step (53,514), smplpix project -> sparse RGB-D inputs
#   baselines per test view: smplpix raster per-vertex colours (both counts), textured (baked)
#   train     per vertex count and seed: stage 1 l1, stage 2 the VGG16 perceptual loss (--loss
#             vgg16, fine-tuning stage 1; skipped, saying so, without the VGG16 weights of
#             `make weights`), stage 3 + multi-scale GAN and feature matching; every stage's
#             network renders the test views and is scored
#   eval      smplpix eval (PSNR, SSIM, LPIPS with the cached weights) full image and mask
#   time      table1_tool time: each renderer's frame in one process, after warm-up
#   report    TABLE1.md and table1.png (ground truth | input | per-vertex | textured | SMPLpix)
# Splits: subjects 0..NTRAIN-1 train, the rest are unseen test subjects; training uses views
# 0..VTRAIN-1 (view VTRAIN of each training subject is the validation set), tests use views
# VTRAIN.. of the test subjects (other poses of the clip and other cameras).
# Resuming: the work dir keeps a done-mark per finished unit (done/), and a stopped run started
# again with the same settings continues from there (an interrupted training stage continues from
# its last saved checkpoint with --resume); other settings are refused unless TABLE1_FRESH=1.
# Environment: TABLE1_QUICK=1 (tiny: checks the pipeline and the files, not the scores),
# TABLE1_OUT (work dir, default out/table1 or out/table1-quick), TABLE1_BUILD (default build),
# TABLE1_REPORT (where TABLE1.md and table1.png go; default benchmarks/, quick: the work dir),
# TABLE1_LPIPS (LPIPS weights for smplpix eval; default: its cached ones), TABLE1_SYNTH (use this
# existing synth output instead of running smplpix synth; its sizes must match the mode's),
# TABLE1_CHECK=1 (check the synth output and its framing, then stop), TABLE1_FRESH=1 (start over), TABLE1_GANLR (the GAN stage's learning rate, default 2e-5), sizes: see
# below. Bad input: one line, exit 1.
set -eu
set -o pipefail

die() { echo "table1: error: $*" >&2; exit 1; }
root=$(cd "$(dirname "$0")/.." && pwd)
build=${TABLE1_BUILD:-$root/build}
tool=$build/smplpix
helper=$build/benchmarks/table1_tool
[ -x "$tool" ] || die "$tool: not built (run make build)"
[ -x "$helper" ] || die "$helper: not built (configure with SPX_BUILD_BENCHMARKS=ON)"
command -v jq >/dev/null || die "jq: not found (apt-get install jq)"

if [ "${TABLE1_QUICK:-0}" = 1 ]; then
  mode=quick SUBJECTS=2 NTRAIN=1 VIEWS=3 VTRAIN=2 SIZE=48x64 WIDTH=8 STEPS=20 VGGSTEPS=6 GANSTEPS=10 BATCH=2
  POINTS=8000 TEX=256 SYNTEX=256 SEEDS=${TABLE1_SEEDS:-7} DISCW=8 SAVE=10 GANLR=2e-5
  out=${TABLE1_OUT:-$root/out/table1-quick}
  report=${TABLE1_REPORT:-$out}
else
  # sized for about 150 minutes on 2 quiet CPU cores (docs/table1.md; times per stage: benchmarks/RESULTS.md)
  mode=full SUBJECTS=${TABLE1_SUBJECTS:-72} NTRAIN=${TABLE1_NTRAIN:-64} VIEWS=${TABLE1_VIEWS:-6} VTRAIN=${TABLE1_VTRAIN:-4}
  SIZE=${TABLE1_SIZE:-192x256} WIDTH=${TABLE1_WIDTH:-16} STEPS=${TABLE1_STEPS:-2000} VGGSTEPS=${TABLE1_VGGSTEPS:-200}
  GANSTEPS=${TABLE1_GANSTEPS:-300} BATCH=${TABLE1_BATCH:-4} POINTS=50000 TEX=1024 SYNTEX=2048 SEEDS=${TABLE1_SEEDS:-1}
  GANLR=${TABLE1_GANLR:-2e-5}
  DISCW=${TABLE1_DISCW:-32} SAVE=100
  out=${TABLE1_OUT:-$root/out/table1}
  report=${TABLE1_REPORT:-$root/benchmarks}
fi
SEED=${SEEDS%% *} # the data's seed: the first training seed
for v in SUBJECTS NTRAIN VIEWS VTRAIN WIDTH STEPS VGGSTEPS GANSTEPS BATCH DISCW; do
  case ${!v} in '' | *[!0-9]*) die "TABLE1_$v=${!v}: expected a whole number" ;; esac
done
for s in $SEEDS; do case $s in *[!0-9]*) die "TABLE1_SEEDS=$SEEDS: expected whole numbers separated by spaces" ;; esac; done
[ -n "$SEED" ] || die "TABLE1_SEEDS is empty"
[ "$NTRAIN" -ge 1 ] && [ "$NTRAIN" -lt "$SUBJECTS" ] || die "TABLE1_NTRAIN=$NTRAIN: need 1..SUBJECTS-1 training subjects"
[ "$VTRAIN" -ge 1 ] && [ "$VTRAIN" -lt "$VIEWS" ] || die "TABLE1_VTRAIN=$VTRAIN: need 1..VIEWS-1 training views"
[ "$STEPS" -ge 1 ] || die "TABLE1_STEPS=$STEPS: need at least 1 step of stage 1"
case $SIZE in [1-9]*x[1-9]*) ;; *) die "TABLE1_SIZE=$SIZE: expected WxH" ;; esac
case $GANLR in '' | *[!0-9.e-]* | *e | e*) die "TABLE1_GANLR=$GANLR: expected a learning rate such as 2e-5" ;; esac

# The perceptual stage needs VGG16 (make weights); LPIPS needs AlexNet's (the eval default).
weights=${SPX_CACHE_DIR:-${HOME:-/nonexistent}/.cache/smplpix}/weights
vgg16=$weights/vgg16.safetensors
# (the help is read whole first: `--help | grep -q` under pipefail fails whenever grep stops
# reading before the tool has written its last block, and would drop a stage at random)
trainhelp=$($tool train --help 2>&1) || trainhelp=
trains() { case $trainhelp in *"$1"*) return 0 ;; esac; return 1; }
vggstage=1
{ [ "$VGGSTEPS" -gt 0 ] && [ -f "$vgg16" ] && trains vgg16; } || vggstage=0
gan=0
[ "$GANSTEPS" -gt 0 ] && trains 'l1+gan' && gan=1
ganloss=l1+gan
[ $vggstage = 1 ] && trains 'vgg16+gan' && ganloss=vgg16+gan

# The work directory: continued when it holds a run of the same settings; a table1 work directory
# (its log.txt) of other settings is replaced when it holds no finished unit or TABLE1_FRESH=1 is
# set, refused otherwise; anything else is refused.
config="mode=$mode subjects=$SUBJECTS ntrain=$NTRAIN views=$VIEWS vtrain=$VTRAIN size=$SIZE width=$WIDTH steps=$STEPS \
vggsteps=$VGGSTEPS/$vggstage gansteps=$GANSTEPS/$ganloss ganlr=$GANLR batch=$BATCH seeds=$SEEDS discw=$DISCW synth=${TABLE1_SYNTH:-}"
if [ -e "$out" ] && { [ ! -d "$out" ] || { [ -n "$(ls -A "$out")" ] && [ ! -f "$out/log.txt" ]; }; }; then
  die "$out: exists and is not a table1 work directory (no log.txt); choose another TABLE1_OUT"
fi
if [ -f "$out/config.txt" ] && [ "$(cat "$out/config.txt")" = "$config" ] && [ "${TABLE1_FRESH:-0}" != 1 ]; then
  resumed=1
else
  if [ -f "$out/config.txt" ] && [ -n "$(ls "$out/done" 2>/dev/null | grep -v '^time\.')" ] && [ "${TABLE1_FRESH:-0}" != 1 ]; then
    die "$out: holds a run with other settings ($(cat "$out/config.txt")); TABLE1_FRESH=1 replaces it"
  fi
  resumed=0
  rm -rf "$out"
fi
mkdir -p "$out/done" "$report" || die "$out or $report: cannot create"
[ $resumed = 1 ] || printf '%s\n' "$config" >"$out/config.txt"
log=$out/log.txt
touch "$log"
t_start=$(date +%s.%N)
# Seconds spent per stage, kept across sittings: wall time (done/time.<stage>) and the CPU time
# of the commands run (done/cpu.<stage>: user + system of every finished child process, from this
# shell's /proc stat; on a machine shared with other work the wall time says little).
hz=$(getconf CLK_TCK)
cpunow() { awk -v hz="$hz" '{ printf "%.2f", ($16 + $17) / hz }' /proc/$$/stat; }
addtime() { # addtime NAME SECONDS [CPU-SECONDS]
  local f=$out/done/time.$1 c=$out/done/cpu.$1 prev=0
  [ -f "$f" ] && prev=$(cat "$f")
  calc "$prev + $2" >"$f.tmp" && mv "$f.tmp" "$f"
  prev=0
  [ -f "$c" ] && prev=$(cat "$c")
  calc "$prev + ${3:-0}" >"$c.tmp" && mv "$c.tmp" "$c"
}
stage() { # stage NAME CMD...: run, log, add the wall and CPU time to stage NAME
  local name=$1 t0 t1 c0
  shift
  t0=$(date +%s.%N) c0=$(cpunow)
  "$@" >>"$log" 2>&1 || die "stage $name: $(tail -n 1 "$log") (log: $log)"
  t1=$(date +%s.%N)
  addtime "$name" "$(calc "$t1 - $t0")" "$(calc "$(cpunow) - $c0")"
}
done_mark() { : >"$out/done/$1"; }
is_done() { [ -f "$out/done/$1" ]; }
now() { date +%s.%N; }
calc() { awk "BEGIN { printf \"%.6f\", $1 }"; }
secs() { calc "$2 - $1"; }
say() { printf 'table1 [%s] %s\n' "$(date -u +%H:%M:%S)" "$*"; }
[ $resumed = 1 ] && say "continuing $out (done: $(ls "$out/done" | grep -vc '^time\.' || true) units)"

# check_framing: the manifest's size is the mode's, every view's camera has that size, and the
# framing the manifest records (smplpix synth: "framing" {"rule", "fill": [lo, hi]}, per view
# "framing" {"fill", "box": [u0, v0, u1, v1], "focal", "center": [cx, cy]}, the posed scan's
# projected box in pixels and the camera's intrinsics) holds for it: the camera's focal length and
# principal point are the ones recorded, the box inside the image, centred, its height (or width)
# `fill` of the image's, fill in the rule's range. A manifest without the "framing" rule is an older synth output: read as it is.
check_framing() {
  local w h
  w=$(jq '.width // empty' "$man") h=$(jq '.height // empty' "$man")
  [ "${w}x${h}" = "$SIZE" ] || die "$manname: photos of ${w:-?}x${h:-?}, but this run's size is $SIZE (TABLE1_SIZE)"
  # each camera: the manifest's size, and (framed) the focal length and principal point recorded
  jq -r '.subjects[].views[] | [.name, .camera, (.framing | tojson)] | @tsv' "$man" | while IFS=$'\t' read -r vname cam fr; do
    jq -e --argjson w "$w" --argjson h "$h" --argjson f "$fr" '.width == $w and .height == $h and
      ($f == null or ((($f.focal | numbers) - .K[0][0] | fabs) <= 1e-6 * $f.focal and
        ($f.center | length) == 2 and ($f.center[0] - .K[0][2] | fabs) <= 1e-6 * $w and
        ($f.center[1] - .K[1][2] | fabs) <= 1e-6 * $h))' "$out/synth/$cam" >/dev/null 2>&1 ||
      die "$manname: view $vname: its camera $cam ($(jq -c '[.width, .height, .K]' "$out/synth/$cam" 2>/dev/null || echo unreadable)) does not match the manifest (${w}x${h}, framing $fr)"
  done || exit 1
  framing=$(jq -r 'if .framing == null then "none" else "\(.framing.rule) \(.framing.fill[0]) \(.framing.fill[1])" end' "$man")
  if [ "$framing" = none ]; then
    framing_note="none recorded (an older synth output: landscape, the subject at a distance)"
    say "framing: $manname records none (an older synth output); read as it is"
    return 0
  fi
  set -- $framing
  framing_note="the posed scan's projected bounding box fills $2..$3 of the photo's height (or width), centred (\`smplpix synth\`, docs/synth.md)"
  local bad
  bad=$(jq -r --argjson w "$w" --argjson h "$h" '
    (.framing.fill // []) as $r |
    if ($r | length) != 2 or ([$r[] | numbers] | length) != 2 then "the framing rule has no fill range [lo, hi]"
    else first(.subjects[].views[] |
      .framing as $f | .name as $n |
      if ($f | type) != "object" or ($f.fill | type) != "number" or ($f.box | type) != "array" or
         ([$f.box[]? | numbers] | length) != 4 then "view \($n): no framing (fill and box)"
      else ($f.box) as $b | (($b[2] - $b[0]) / $w) as $fw | (($b[3] - $b[1]) / $h) as $fh |
        if $b[0] < -0.5 or $b[1] < -0.5 or $b[2] > $w + 0.5 or $b[3] > $h + 0.5 then "view \($n): its box \($b) leaves the \($w)x\($h) image"
        elif ((($b[0] + $b[2]) / 2 - $w / 2) | fabs) > 1 or ((($b[1] + $b[3]) / 2 - $h / 2) | fabs) > 1 then "view \($n): its box \($b) is not centred"
        elif ((([$fw, $fh] | max) - $f.fill) | fabs) > 0.005 then "view \($n): its box fills \([$fw, $fh] | max) of the image, not its fill \($f.fill)"
        elif $f.fill < $r[0] - 1e-9 or $f.fill > $r[1] + 1e-9 then "view \($n): fill \($f.fill) outside the range \($r) of the rule"
        else empty end
      end) // empty
    end' "$man" 2>/dev/null) || die "$manname: the framing cannot be read"
  [ -z "$bad" ] || die "$manname: framing inconsistent with the cameras: $bad"
  say "framing: rule $1, fill $2..$3; every view checked against its camera"
}

# ---- synth ------------------------------------------------------------------------------------
say "$mode: $SUBJECTS subjects ($NTRAIN train) x $VIEWS views ($VTRAIN train), ${SIZE}, width $WIDTH, seeds $SEEDS"
if ! is_done synth; then
  rm -rf "$out/synth"
  if [ -n "${TABLE1_SYNTH:-}" ]; then # an existing `smplpix synth` output (read only; copied)
    [ -f "$TABLE1_SYNTH/synth.json" ] || die "$TABLE1_SYNTH/synth.json: no such file (TABLE1_SYNTH)"
    cp -r "$TABLE1_SYNTH" "$out/synth"
  else
    $tool synth --help >/dev/null 2>&1 || die "smplpix synth: not in this build"
    stage synth $tool synth --subjects "$SUBJECTS" --views "$VIEWS" --seed "$SEED" --out "$out/synth" --size "$SIZE" \
      --texture-size "$SYNTEX" --quiet
  fi
fi
man=$out/synth/synth.json
manname=${TABLE1_SYNTH:+$TABLE1_SYNTH/synth.json}
manname=${manname:-$man}
[ -f "$man" ] || die "$manname: smplpix synth wrote no manifest"
jq empty "$man" >/dev/null 2>&1 || die "$manname: not valid JSON"
jq -e '.subjects | length > 0' "$man" >/dev/null 2>&1 || die "$manname: no subjects"
nsub=$(jq '.subjects | length' "$man")
[ "$nsub" = "$SUBJECTS" ] || die "$manname: $nsub subjects, expected $SUBJECTS"

jq -e '([.subjects[] | (.name, .scan | strings), (.views | length),
          (.views[] | .name, .camera, .image, .mask, .pose.source | strings)] | length)
       == ([.subjects[] | 3 + 5 * (.views | length)] | add)' "$man" >/dev/null 2>&1 ||
  die "$manname: every subject needs a name, a scan and views with name, camera, image, mask and pose.source"
# views as lines: subject_index view_index name camera image mask pose_source
jq -r '.subjects | to_entries[] | .key as $s | .value.views | to_entries[] |
       [$s, .key, .value.name, .value.camera, .value.image, .value.mask, .value.pose.source] | @tsv' "$man" >"$out/views.tsv"

while IFS=$'\t' read -r si vi vname cam img mask src; do
  for f in "$cam" "$img" "$mask"; do [ -f "$out/synth/$f" ] || die "$manname: view $vname: $f: no such file"; done
  [ "$vi" -lt "$VIEWS" ] || die "$manname: subject $si has more than $VIEWS views"
done <"$out/views.tsv"
[ "$(wc -l <"$out/views.tsv")" = $((SUBJECTS * VIEWS)) ] || die "$manname: expected $VIEWS views per subject"
check_framing
done_mark synth
if [ "${TABLE1_CHECK:-0}" = 1 ]; then say "checked $manname (TABLE1_CHECK=1: nothing else is run)"; exit 0; fi

# ---- register + bake --------------------------------------------------------------------------
say "register: $SUBJECTS scans ($POINTS-point clouds), bake ${TEX}x${TEX} textures"
for s in $(seq 0 $((SUBJECTS - 1))); do
  name=$(jq -r ".subjects[$s].name" "$man")
  is_done "register.$name" && continue
  scan=$out/synth/$(jq -r ".subjects[$s].scan" "$man")
  d=$out/subjects/$name
  mkdir -p "$d"
  stage register "$helper" sample --mesh "$scan" --points "$POINTS" --seed "$((SEED * 1000 + s))" --out "$d/cloud.ply"
  stage register $tool register --scan "$d/cloud.ply" --out "$d/reg.ply" --params "$d/reg.json" --threads 2 --units m
  stage bake $tool bake --mesh "$d/reg.ply" --scan "$scan" --out "$d/texture.png" --size "$TEX"
  done_mark "register.$name"
done

# ---- inputs and baselines ---------------------------------------------------------------------
say "inputs: repose to every view's pose, project at 13k and 53k vertices; rasterize the test views"
for n in 13k 53k; do
  for split in train validation test; do mkdir -p "$out/data$n/$split/input" "$out/data$n/$split/output"; done
done
mkdir -p "$out/methods/gt" "$out/methods/mask" "$out/methods/pervertex13k" "$out/methods/pervertex53k" \
  "$out/methods/textured13k" "$out/methods/input13k"
quiet() { "$@" >>"$log" 2>&1 || die "$1 ${2:-}: $(tail -n 1 "$log") (log: $log)"; }
t0=$(now) c0=$(cpunow)
first_test=
while IFS=$'\t' read -r si vi vname cam img mask src; do
  subj=$(jq -r ".subjects[$si].name" "$man")
  d=$out/subjects/$subj
  if [ "$si" -lt "$NTRAIN" ]; then
    if [ "$vi" -lt "$VTRAIN" ]; then split=train; elif [ "$vi" = "$VTRAIN" ]; then split=validation; else continue; fi
  else
    [ "$vi" -ge "$VTRAIN" ] || continue # unseen subjects: only the test poses and cameras
    split=test
    [ -n "$first_test" ] || first_test="$d/$vname $out/synth/$cam"
  fi
  is_done "inputs.$vname" && continue
  quiet $tool repose --registration "$d/reg.json" --pose "$man" --view "$vname" --out "$d/$vname.13k.obj"
  quiet $tool repose --registration "$d/reg.json" --pose "$man" --view "$vname" --subdivide 1 --out "$d/$vname.53k.ply"
  for n in 13k 53k; do
    # one input per view (the RGB-D EXR); the grid's PNG of a test input goes beside the methods
    ext=obj png=() && [ $n = 53k ] && ext=ply
    [ $split = test ] && [ $n = 13k ] && png=(--png "$out/methods/input13k/$vname.png")
    quiet $tool project --mesh "$d/$vname.$n.$ext" --camera "$out/synth/$cam" --out "$out/data$n/$split/input/$vname.exr" \
      "${png[@]}" --color mesh --quiet
    cp "$out/synth/$img" "$out/data$n/$split/output/$vname.png"
  done
  if [ $split = test ]; then
    cp "$out/synth/$img" "$out/methods/gt/$vname.png"
    cp "$out/synth/$mask" "$out/methods/mask/$vname.png"
    quiet $tool raster --mesh "$d/$vname.13k.obj" --camera "$out/synth/$cam" --out "$out/methods/pervertex13k/$vname.png" --color mesh --aa 2 --quiet
    quiet $tool raster --mesh "$d/$vname.53k.ply" --camera "$out/synth/$cam" --out "$out/methods/pervertex53k/$vname.png" --color mesh --aa 2 --quiet
    quiet $tool raster --mesh "$d/$vname.13k.obj" --camera "$out/synth/$cam" --texture "$d/texture.png" \
      --out "$out/methods/textured13k/$vname.png" --aa 2 --quiet
  fi
  done_mark "inputs.$vname"
done <"$out/views.tsv"
addtime inputs "$(secs "$t0" "$(now)")" "$(calc "$(cpunow) - $c0")"
ntest=$(ls "$out/methods/gt" | wc -l)
[ "$ntest" -gt 0 ] || die "$manname: no test views (need subjects >= $((NTRAIN + 1)) with views >= $((VTRAIN + 1)))"

# test poses never seen in training: compare the pose sources of the two splits
seen=$(awk -F'\t' -v nt="$NTRAIN" -v vt="$VTRAIN" '$1 < nt && $2 < vt {print $7}' "$out/views.tsv" | sort -u)
overlap=$(awk -F'\t' -v nt="$NTRAIN" -v vt="$VTRAIN" '$1 >= nt && $2 >= vt {print $7}' "$out/views.tsv" | sort -u |
  grep -Fxc -f <(printf '%s\n' "$seen") || true)
frames() { # frames SUBJECT_TEST VIEW_TEST: "min..max" of the BVH frames of those views
  awk -F'\t' -v nt="$NTRAIN" -v vt="$VTRAIN" -v st="$1" -v sv="$2" '
    (st ? $1 >= nt : $1 < nt) && (sv ? $2 >= vt : $2 < vt) && $7 ~ /^bvh:/ {
      f = substr($7, 5) + 0; if (n++ == 0 || f < lo) lo = f; if (f > hi) hi = f }
    END { print n ? lo ".." hi : "none" }' "$out/views.tsv"
}
train_frames=$(frames 0 0) test_frames=$(frames 1 1)

# ---- eval helper --------------------------------------------------------------------------------
have_eval=0
$tool eval --help >/dev/null 2>&1 && have_eval=1
lpips_cached=$weights/lpips_alex.safetensors
lpips_src=${TABLE1_LPIPS:-}
[ -z "$lpips_src" ] && [ -f "$lpips_cached" ] && lpips_src=$lpips_cached
[ -n "$lpips_src" ] || say "eval: no LPIPS weights ($lpips_cached is absent: run make weights); LPIPS is n/a"
lp=()
[ -n "${TABLE1_LPIPS:-}" ] && lp=(--lpips "$TABLE1_LPIPS")
score() { # score METHOD_DIR JSON: smplpix eval against the ground truth, full image and mask
  [ $have_eval = 1 ] || return 0
  local t0 c0
  t0=$(now) c0=$(cpunow)
  quiet $tool eval --pred "$1" --target "$out/methods/gt" --mask "$out/methods/mask" --json "$2.tmp.json" "${lp[@]}"
  mv "$2.tmp.json" "$2"
  addtime eval "$(secs "$t0" "$(now)")" "$(calc "$(cpunow) - $c0")"
}
for m in pervertex13k pervertex53k textured13k; do
  is_done "eval.$m" || { score "$out/methods/$m" "$out/eval_$m.json" && done_mark "eval.$m"; }
done

# ---- train: per vertex count and seed, three stages, each scored ------------------------------
# train_stage KEY LOSS STEPS LR INIT [EXTRA...]: one `smplpix train` to $out/KEY.safetensors, continued
# with --resume after an interruption; then its network renders every test view and is scored.
train_stage() {
  local key=$1 loss=$2 steps=$3 lr=$4 init=$5 n=$6 seed=$7
  shift 7
  local w=$out/$key.safetensors
  is_done "train.$key" && return 0
  if [ -f "$w" ]; then
    stage "train$n" $tool train --data "$out/data$n" --out "$w" --resume --steps "$steps" --log-every 50
  else
    local from=()
    [ -n "$init" ] && from=(--init "$init")
    stage "train$n" $tool train --data "$out/data$n" --out "$w" --width "$WIDTH" --batch "$BATCH" --lr "$lr" \
      --steps "$steps" --seed "$seed" --loss "$loss" --log-every 50 --save-every "$SAVE" "${from[@]}" "$@"
  fi
  done_mark "train.$key"
}
render_score() { # render_score KEY n: every test input through $out/KEY.safetensors, then eval
  local key=$1 n=$2 dir=$out/methods/$1 f v
  is_done "eval.$key" && return 0
  rm -rf "$dir" && mkdir -p "$dir"
  for f in "$out/data$n/test/input/"*.exr; do
    v=$(basename "$f" .exr)
    quiet $tool render --checkpoint "$out/$key.safetensors" --input "$f" --out "$dir/$v.png" --quiet
  done
  score "$dir" "$out/eval_$key.json"
  done_mark "eval.$key"
}
stages="1"
[ $vggstage = 1 ] && stages="$stages 2"
[ $gan = 1 ] && stages="$stages 3"
last=${stages##* }
[ $vggstage = 1 ] || say "stage 2 (VGG16 perceptual) skipped: $vgg16 is absent (make weights) or VGGSTEPS=0"
for n in 13k 53k; do
  for seed in $SEEDS; do
    say "train $n, seed $seed: stages $stages (l1 $STEPS, vgg16 $VGGSTEPS, $ganloss $GANSTEPS steps)"
    k=unet$n.s$seed
    train_stage "$k.stage1" l1 "$STEPS" 2e-3 "" $n "$seed"
    render_score "$k.stage1" $n
    prev=$out/$k.stage1.safetensors
    if [ $vggstage = 1 ]; then
      train_stage "$k.stage2" vgg16 "$VGGSTEPS" 2e-4 "$prev" $n "$seed" --vgg "$vgg16"
      render_score "$k.stage2" $n
      prev=$out/$k.stage2.safetensors
    fi
    if [ $gan = 1 ]; then
      vggarg=()
      [ $ganloss = vgg16+gan ] && vggarg=(--vgg "$vgg16")
      train_stage "$k.stage3" "$ganloss" "$GANSTEPS" "$GANLR" "$prev" $n "$seed" --disc-width "$DISCW" "${vggarg[@]}"
      render_score "$k.stage3" $n
    fi
  done
  # the final network of the first seed is this vertex count's SMPLpix (shipped, timed, in the grid)
  cp "$out/unet$n.s$SEED.stage$last.safetensors" "$out/unet$n.safetensors"
  rm -rf "$out/methods/smplpix$n" && cp -r "$out/methods/unet$n.s$SEED.stage$last" "$out/methods/smplpix$n"
done

# ---- time per frame, in process ---------------------------------------------------------------
# one test view (the first), every renderer in one process after warm-up (table1_tool time)
say "time: each renderer's frame on one test view, in process"
set -- $first_test
tview=$1 tcam=$2
tex=$(dirname "$tview")/texture.png
declare -A ms
frames_n=20
[ $mode = quick ] && frames_n=3
parse_ms() { awk -v k="$1" '$1 == k {printf "%.1f", $2}' "$out/time_$2.txt"; }
for n in 13k 53k; do
  ext=obj && [ $n = 53k ] && ext=ply
  if ! is_done "time.$n"; then
    args=(--mesh "$tview.$n.$ext" --camera "$tcam" --checkpoint "$out/unet$n.safetensors" --frames $frames_n)
    [ $n = 13k ] && args+=(--texture "$tex")
    "$helper" time "${args[@]}" >"$out/time_$n.txt.tmp" 2>>"$log" || die "time: $(tail -n 1 "$log") (log: $log)"
    mv "$out/time_$n.txt.tmp" "$out/time_$n.txt"
    done_mark "time.$n"
  fi
  ms[smplpix$n]=$(parse_ms smplpix_ms $n) ms[pervertex$n]=$(parse_ms raster_ms $n)
  [ $n = 13k ] && ms[textured13k]=$(parse_ms textured_ms $n)
done

# ---- report -----------------------------------------------------------------------------------
grid_imgs=()
for v in $(ls "$out/methods/gt" | head -n 4); do
  grid_imgs+=("$out/methods/gt/$v" "$out/methods/input13k/$v" "$out/methods/pervertex13k/$v" "$out/methods/textured13k/$v"
    "$out/methods/smplpix13k/$v")
done
"$helper" grid --out "$out/table1.png.tmp.png" --cols 5 "${grid_imgs[@]}" >>"$log" 2>&1 || die "grid: $(tail -n 1 "$log") (log: $log)"

# stat KEY FIELD: the mean over seeds of FIELD in eval_unet<KEY>.s<seed>.json files (KEY = 13k.stage1 ...),
# with the spread (min..max) when there are several seeds; for a baseline method, its value
stat() {
  local files=() s
  case $1 in
  pervertex* | textured*) files=("$out/eval_$1.json") ;;
  *) for s in $SEEDS; do files+=("$out/eval_unet${1%%.*}.s$s.${1#*.}.json"); done ;;
  esac
  for f in "${files[@]}"; do [ -f "$f" ] || { echo "—"; return; }; done
  jq -rs --arg k "$2" 'map(.[$k]) | if all(type == "number") then
      (add / length) as $m | (min) as $lo | (max) as $hi |
      if length > 1 then "\($m * 1000 | round / 1000) (\($lo * 1000 | round / 1000)..\($hi * 1000 | round / 1000))"
      else "\($m * 1000 | round / 1000)" end
    else "—" end' "${files[@]}"
}
mean() { stat "$1" "$2" | awk '{print $1}'; }
stage_label() {
  case $1 in
  1) echo "stage 1: l1, $STEPS steps" ;;
  2) echo "stage 2: VGG16 perceptual, $VGGSTEPS steps from stage 1" ;;
  3) echo "stage 3: $ganloss (PatchGAN x3 + 0.1 feature matching), $GANSTEPS steps" ;;
  esac
}
total=$(secs "$t_start" "$(now)")
md=$out/TABLE1.md.tmp
nseeds=$(echo $SEEDS | wc -w)
{
  echo "# Table 1 on synthetic scanned people ($mode run)"
  echo
  echo "The paper's Table 1 (SMPLpix vs mesh rasterization) reproduced on \`smplpix synth\` subjects: every"
  echo "method renders the same $ntest test views of $((SUBJECTS - NTRAIN)) unseen subjects, in poses and from cameras"
  echo "never seen in training. Scores from \`smplpix eval\` (mean over the test views), full image and inside"
  echo "the subject's mask$([ $nseeds -gt 1 ] && echo "; SMPLpix rows: mean over $nseeds training seeds ($SEEDS), (min..max) over the seeds")."
  echo "Detail: the mean absolute image gradient of the rendering over the photo's (1 = as much edge and print"
  echo "detail as the photo, below 1 = blurred; \`smplpix eval\`), over the whole image and inside the mask."
  echo "Time per frame: one renderer's frame in one process after warm-up (\`table1_tool time\`: upload the"
  echo "posed vertices, render, read the image back; SMPLpix = projection + network), on one test view."
  echo
  echo "| method | vertices | PSNR full | SSIM full | LPIPS full | detail full | PSNR mask | SSIM mask | LPIPS mask | detail mask | time/frame (ms) |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|"
  row() { # row LABEL VERTS KEY TIME
    echo "| $1 | $2 | $(stat "$3" psnr) | $(stat "$3" ssim) | $(stat "$3" lpips) | $(stat "$3" detail_full) | $(stat "$3" psnr_masked) | $(stat "$3" ssim_masked) | $(stat "$3" lpips_masked) | $(stat "$3" detail) | $4 |"
  }
  v13="13,380" v53="53,514 (1 Loop step; paper: 27k)"
  row "per-vertex colours, rasterized (paper: NMR per-verts)" "$v13" pervertex13k "${ms[pervertex13k]:-—}"
  row "per-vertex colours, rasterized (paper: NMR per-verts)" "$v53" pervertex53k "${ms[pervertex53k]:-—}"
  row "full texture baked from the scan, rasterized (paper: NMR full textures)" "$v13" textured13k "${ms[textured13k]:-—}"
  for n in 13k 53k; do
    vv=$v13 && [ $n = 53k ] && vv=$v53
    for st in $stages; do
      row "SMPLpix, $(stage_label $st)" "$vv" "$n.stage$st" "$([ $st = $last ] && echo "${ms[smplpix$n]:-—}" || echo "")"
    done
  done
  echo
  if [ $have_eval = 1 ]; then
    for n in 13k 53k; do
      awk -v n="$n" -v pv="$(mean pervertex$n psnr)" -v sp="$(mean $n.stage$last psnr)" -v lpv="$(mean pervertex$n lpips)" \
        -v lsp="$(mean $n.stage$last lpips)" -v ltx="$(mean textured13k lpips)" -v dsp="$(mean $n.stage$last detail)" \
        -v dpv="$(mean pervertex$n detail)" 'BEGIN {
        if (pv == "—" || sp == "—") { printf "Goal, %s: not evaluated (a PSNR is missing).\n", n; exit }
        d = sp - pv
        printf "Goal, %s vertices, final stage: SMPLpix - per-vertex = %+.2f dB PSNR (goal >= +2.0: %s)", n, d, (d >= 2 ? "met" : "not met")
        if (dsp != "—") printf "; detail in the mask %.2f of the photo'"'"'s (goal >= 0.9: %s; per-vertex raster %s)", dsp, (dsp >= 0.9 ? "met" : "not met"), dpv
        if (lpv == "—" || lsp == "—" || ltx == "—") { printf "; LPIPS not measured (make weights).\n"; exit }
        r = lsp / lpv
        printf "; LPIPS SMPLpix / per-vertex = %.2f (goal <= 0.75: %s), SMPLpix %s the textured raster (%.3f; goal: below).\n", r, (r <= 0.75 ? "met" : "not met"), (lsp < ltx ? "below" : "not below"), ltx }'
    done
  else
    echo "**No scores: \`smplpix eval\` is not in this build; the images are in $out/methods.**"
  fi
  echo
  echo "## Setup"
  echo
  echo "- Data: \`smplpix synth --subjects $SUBJECTS --views $VIEWS --seed $SEED --size $SIZE --texture-size $SYNTEX\`; subjects 0..$((NTRAIN - 1)) train"
  echo "  (views 0..$((VTRAIN - 1)); view $VTRAIN of each is the validation set), subjects $NTRAIN..$((SUBJECTS - 1)) test (views $VTRAIN..$((VIEWS - 1)))."
  echo "  BVH frames of the training views: $train_frames (plus rest poses); of the test views: $test_frames;"
  echo "  test pose sources also used in training: $overlap. Framing: $framing_note."
  echo "- Registration: a $POINTS-point coloured cloud sampled from each scan (\`table1_tool sample\`), \`smplpix register\`"
  echo "  (rigid, pose, free); the registered vertices and colours are reposed to each view's pose"
  echo "  (\`smplpix repose --pose synth.json --view NAME\`), at 13,380 vertices and after one Loop step (53,514;"
  echo "  the paper's 27k row is one subdivision of its 7k body). Texture: \`smplpix bake\` (${TEX}x${TEX})."
  echo "- Rasterizers: \`smplpix raster --aa 2\` (2x2 supersampling, as the synth photos), unlit colours."
  if [ -n "$lpips_src" ]; then
    echo "- LPIPS: v0.1 AlexNet as the \`lpips\` package computes it (\`smplpix eval\`), weights $lpips_src"
    echo "  ($([ "$lpips_src" = "$lpips_cached" ] && echo 'from `make weights`' || echo 'TABLE1_LPIPS'))."
  else
    echo "- LPIPS: not measured (no weights: \`make weights\` puts them in $lpips_cached)."
  fi
  echo "- Network: UNet width $WIDTH, batch $BATCH, Adam; stage 1 \`--loss l1\` $STEPS steps at lr 2e-3;"
  if [ $vggstage = 1 ]; then
    echo "  stage 2 \`--loss vgg16\` (the official SMPLpix re-implementation's VGG16 loss, ImageNet weights from \`make weights\`) $VGGSTEPS steps at lr 2e-4 from stage 1;"
  else
    echo "  stage 2 (VGG16 perceptual) not run: no VGG16 weights (\`make weights\`);"
  fi
  [ $gan = 1 ] && echo "  stage 3 \`--loss $ganloss\` $GANSTEPS steps at lr $GANLR (a tenth of stage 2's, as the paper's stage 2 is of its stage 1) from the previous stage, PatchGAN width $DISCW;"
  echo "  seeds $SEEDS (the data's seed: $SEED). Validation during training: view $VTRAIN of each training subject."
  echo "- Time per stage (s): $(for k in synth register bake inputs train13k train53k eval; do printf '%s %.0f, ' "$([ $k = inputs ] && echo 'inputs+rasterizers' || echo $k)" "$(cat "$out/done/time.$k" 2>/dev/null || echo 0)"; done)this sitting $(printf '%.0f' "$total");"
  echo "  CPU time per stage (s, user + system of the commands, all sittings): $(for k in synth register bake inputs train13k train53k eval; do printf '%s %.0f, ' "$([ $k = inputs ] && echo 'inputs+rasterizers' || echo $k)" "$(cat "$out/done/cpu.$k" 2>/dev/null || echo 0)"; done | sed 's/, $//'); in all $(awk '{ s += $1 } END { printf "%.0f s = %.0f minutes of 2 cores", s, s / 120 }' "$out"/done/cpu.* 2>/dev/null)."
  echo "- Machine: $(uname -srm), $(nproc) CPU cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')), load average at the end $(cut -d' ' -f1-3 /proc/loadavg), OpenCL device: $($tool devices 2>/dev/null | head -n 1 | sed 's/^ *//')."
  echo "- Command: \`$([ $mode = quick ] && echo 'TABLE1_QUICK=1 ')make table1\`, $(date -u '+%Y-%m-%d %H:%M UTC'); grid: table1.png (rows: test views;"
  echo "  columns: ground truth | input projection | per-vertex raster | textured raster | SMPLpix, 13k, final stage)."
} >"$md"
mv "$out/table1.png.tmp.png" "$report/table1.png"
mv "$md" "$report/TABLE1.md"
say "wrote $report/TABLE1.md and $report/table1.png in $(printf '%.0f' "$total") s"
