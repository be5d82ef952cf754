#!/usr/bin/env bash
# make table1: the paper's experiment (Table 1 of SMPLpix, WACV 2021) end to end on synthetic
# scanned people. Stages (each timed):
#   synth     smplpix synth: subjects (scan, cameras, view poses, ground-truth photos)
#   register  per subject: a coloured point cloud sampled from the scan (table1_tool sample),
#             smplpix register (rigid, pose, free), smplpix bake (scan colours -> body UV texture)
#   inputs    per view: smplpix repose (the view's pose from synth.json) at 13,380 vertices and
#             after 1 Loop step (53,514), smplpix project -> sparse RGB-D inputs
#   baselines per test view: smplpix raster per-vertex colours (both counts), textured (baked)
#   train     smplpix train --loss l1 (stage 1), then --loss l1+gan when the tool has it (stage 2)
#   render    smplpix render on every test input
#   eval      smplpix eval (PSNR, SSIM, LPIPS with the weights of `make weights` or TABLE1_LPIPS)
#             full image and mask
#   report    TABLE1.md and table1.png (ground truth | input | per-vertex | textured | SMPLpix)
# Splits: subjects 0..NTRAIN-1 train, the rest are unseen test subjects; training uses views
# 0..VTRAIN-1 (view VTRAIN of each training subject is the validation set), tests use views
# VTRAIN.. of the test subjects (other poses of the clip and other cameras).
# Environment: TABLE1_QUICK=1 (tiny, < 5 min: checks the pipeline and the files, not the
# scores), TABLE1_OUT (work dir, default out/table1 or out/table1-quick), TABLE1_BUILD (default
# build), TABLE1_REPORT (where TABLE1.md and table1.png go; default benchmarks/, quick: the work
# dir), TABLE1_LPIPS (LPIPS weights for smplpix eval; default: the cached ones of `make weights`,
# ${SPX_CACHE_DIR:-~/.cache/smplpix}/weights/lpips_alex.safetensors), TABLE1_SYNTH (use this existing synth
# output instead of running smplpix synth; its sizes must match the mode's). Bad input: one line, exit 1.
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
  mode=quick SUBJECTS=2 NTRAIN=1 VIEWS=3 VTRAIN=2 SIZE=64x48 WIDTH=8 STEPS=20 GANSTEPS=10 BATCH=2
  POINTS=8000 TEX=256 SYNTEX=256 SEED=7 DISCW=8
  out=${TABLE1_OUT:-$root/out/table1-quick}
  report=${TABLE1_REPORT:-$out}
else
  # 60 minutes on 2 CPU cores: see README "make table1" for the time per stage.
  mode=full SUBJECTS=${TABLE1_SUBJECTS:-8} NTRAIN=${TABLE1_NTRAIN:-6} VIEWS=${TABLE1_VIEWS:-16} VTRAIN=${TABLE1_VTRAIN:-12}
  SIZE=${TABLE1_SIZE:-128x96} WIDTH=${TABLE1_WIDTH:-16} STEPS=${TABLE1_STEPS:-3000} GANSTEPS=${TABLE1_GANSTEPS:-500}
  BATCH=${TABLE1_BATCH:-4} POINTS=50000 TEX=1024 SYNTEX=2048 SEED=${TABLE1_SEED:-1}
  DISCW=${TABLE1_DISCW:-32}
  out=${TABLE1_OUT:-$root/out/table1}
  report=${TABLE1_REPORT:-$root/benchmarks}
fi
[ "$NTRAIN" -ge 1 ] && [ "$NTRAIN" -lt "$SUBJECTS" ] || die "TABLE1_NTRAIN=$NTRAIN: need 1..SUBJECTS-1 training subjects"
[ "$VTRAIN" -ge 1 ] && [ "$VTRAIN" -lt "$VIEWS" ] || die "TABLE1_VTRAIN=$VTRAIN: need 1..VIEWS-1 training views"

# the work directory is replaced: only when it is one (its log.txt) or empty
if [ -e "$out" ] && { [ ! -d "$out" ] || { [ -n "$(ls -A "$out")" ] && [ ! -f "$out/log.txt" ]; }; }; then
  die "$out: exists and is not a table1 work directory (no log.txt); choose another TABLE1_OUT"
fi
rm -rf "$out"
mkdir -p "$out" "$report" || die "$out or $report: cannot create"
log=$out/log.txt
: >"$log"
t_start=$(date +%s.%N)
declare -A stage_s
stage() { # stage NAME CMD...: run, log, add the wall time to stage_s[NAME]
  local name=$1 t0 t1
  shift
  t0=$(date +%s.%N)
  "$@" >>"$log" 2>&1 || die "stage $name: $(tail -n 1 "$log") (log: $log)"
  t1=$(date +%s.%N)
  stage_s[$name]=$(calc "${stage_s[$name]:-0} + $t1 - $t0")
}
now() { date +%s.%N; }
calc() { awk "BEGIN { printf \"%.6f\", $1 }"; }
secs() { calc "$2 - $1"; }
say() { printf 'table1 [%s] %s\n' "$(date -u +%H:%M:%S)" "$*"; }

# ---- synth ------------------------------------------------------------------------------------
say "$mode: $SUBJECTS subjects ($NTRAIN train) x $VIEWS views ($VTRAIN train), ${SIZE}, width $WIDTH, seed $SEED"
if [ -n "${TABLE1_SYNTH:-}" ]; then # an existing `smplpix synth` output (read only; copied)
  [ -f "$TABLE1_SYNTH/synth.json" ] || die "$TABLE1_SYNTH/synth.json: no such file (TABLE1_SYNTH)"
  cp -r "$TABLE1_SYNTH" "$out/synth"
else
  $tool synth --help >/dev/null 2>&1 || die "smplpix synth: not in this build (branch h/synth not merged)"
  stage synth $tool synth --subjects "$SUBJECTS" --views "$VIEWS" --seed "$SEED" --out "$out/synth" --size "$SIZE" \
    --texture-size "$SYNTEX" --quiet
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

# ---- register + bake --------------------------------------------------------------------------
say "register: $SUBJECTS scans ($POINTS-point clouds), bake ${TEX}x${TEX} textures"
for s in $(seq 0 $((SUBJECTS - 1))); do
  name=$(jq -r ".subjects[$s].name" "$man")
  scan=$out/synth/$(jq -r ".subjects[$s].scan" "$man")
  d=$out/subjects/$name
  mkdir -p "$d"
  stage register "$helper" sample --mesh "$scan" --points "$POINTS" --seed "$((SEED * 1000 + s))" --out "$d/cloud.ply"
  stage register $tool register --scan "$d/cloud.ply" --out "$d/reg.ply" --params "$d/reg.json" --threads 2 --units m
  stage bake $tool bake --mesh "$d/reg.ply" --scan "$scan" --out "$d/texture.png" --size "$TEX"
done

# ---- inputs and baselines ---------------------------------------------------------------------
say "inputs: repose to every view's pose, project at 13k and 53k vertices; rasterize the test views"
declare -A t_frames n_frames
for n in 13k 53k; do
  for split in train validation test; do mkdir -p "$out/data$n/$split/input" "$out/data$n/$split/output"; done
done
mkdir -p "$out/methods/gt" "$out/methods/mask" "$out/methods/pervertex13k" "$out/methods/pervertex53k" \
  "$out/methods/textured13k" "$out/methods/smplpix13k" "$out/methods/smplpix53k" "$out/methods/input13k"
timed() { # timed KEY CMD...: run once, add the wall time to t_frames[KEY] (one frame per call)
  local key=$1 t0 t1
  shift
  t0=$(now)
  "$@" >>"$log" 2>&1 || die "$key: $(tail -n 1 "$log") (log: $log)"
  t1=$(now)
  t_frames[$key]=$(calc "${t_frames[$key]:-0} + $t1 - $t0")
  n_frames[$key]=$((${n_frames[$key]:-0} + 1))
}
ntest=0
t0=$(now)
while IFS=$'\t' read -r si vi vname cam img mask src; do
  subj=$(jq -r ".subjects[$si].name" "$man")
  d=$out/subjects/$subj
  if [ "$si" -lt "$NTRAIN" ]; then
    if [ "$vi" -lt "$VTRAIN" ]; then split=train; elif [ "$vi" = "$VTRAIN" ]; then split=validation; else continue; fi
  else
    [ "$vi" -ge "$VTRAIN" ] || continue # unseen subjects: only the test poses and cameras
    split=test
  fi
  $tool repose --registration "$d/reg.json" --pose "$man" --view "$vname" --out "$d/$vname.13k.obj" >>"$log" 2>&1 ||
    die "repose: $(tail -n 1 "$log") (log: $log)"
  $tool repose --registration "$d/reg.json" --pose "$man" --view "$vname" --subdivide 1 --out "$d/$vname.53k.ply" >>"$log" 2>&1 ||
    die "repose: $(tail -n 1 "$log") (log: $log)"
  for n in 13k 53k; do
    ext=obj && [ $n = 53k ] && ext=ply
    timed "project$n" $tool project --mesh "$d/$vname.$n.$ext" --camera "$out/synth/$cam" --out "$out/data$n/$split/input/$vname.exr" \
      --png "$out/data$n/$split/input/$vname.png" --color mesh --quiet
    cp "$out/synth/$img" "$out/data$n/$split/output/$vname.png"
  done
  if [ $split = test ]; then
    ntest=$((ntest + 1))
    cp "$out/synth/$img" "$out/methods/gt/$vname.png"
    cp "$out/synth/$mask" "$out/methods/mask/$vname.png"
    cp "$out/data13k/test/input/$vname.png" "$out/methods/input13k/$vname.png"
    timed raster13k $tool raster --mesh "$d/$vname.13k.obj" --camera "$out/synth/$cam" --out "$out/methods/pervertex13k/$vname.png" --color mesh --aa 2 --quiet
    timed raster53k $tool raster --mesh "$d/$vname.53k.ply" --camera "$out/synth/$cam" --out "$out/methods/pervertex53k/$vname.png" --color mesh --aa 2 --quiet
    timed textured $tool raster --mesh "$d/$vname.13k.obj" --camera "$out/synth/$cam" --texture "$d/texture.png" \
      --out "$out/methods/textured13k/$vname.png" --aa 2 --quiet
  fi
done <"$out/views.tsv"
stage_s[inputs]=$(secs "$t0" "$(now)")
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

# ---- train ------------------------------------------------------------------------------------
gan=0
$tool train --help 2>&1 | grep -q 'l1+gan' && gan=1
for n in 13k 53k; do
  say "train $n: width $WIDTH, $STEPS steps of l1$([ $gan = 1 ] && echo ", then $GANSTEPS of l1+gan")"
  stage "train$n" $tool train --data "$out/data$n" --out "$out/unet$n.stage1.safetensors" --width "$WIDTH" --batch "$BATCH" \
    --lr 2e-3 --steps "$STEPS" --seed "$SEED" --loss l1 --log-every 50
  ckpt=$out/unet$n.stage1.safetensors
  if [ $gan = 1 ]; then
    stage "train$n" $tool train --data "$out/data$n" --out "$out/unet$n.stage2.safetensors" --width "$WIDTH" --batch "$BATCH" \
      --lr 2e-4 --steps "$GANSTEPS" --seed "$SEED" --loss l1+gan --disc-width "$DISCW" --init "$ckpt" --log-every 50
    ckpt=$out/unet$n.stage2.safetensors
  fi
  cp "$ckpt" "$out/unet$n.safetensors"
  for f in "$out/data$n/test/input/"*.exr; do
    v=$(basename "$f" .exr)
    timed "unet$n" $tool render --checkpoint "$out/unet$n.safetensors" --input "$f" --out "$out/methods/smplpix$n/$v.png" --quiet
  done
done

# ---- eval -------------------------------------------------------------------------------------
lpips_cached=${SPX_CACHE_DIR:-${HOME:-}/.cache/smplpix}/weights/lpips_alex.safetensors
lpips_src=${TABLE1_LPIPS:-}
[ -z "$lpips_src" ] && [ -f "$lpips_cached" ] && lpips_src=$lpips_cached
methods="pervertex13k pervertex53k textured13k smplpix13k smplpix53k"
have_eval=0
$tool eval --help >/dev/null 2>&1 && have_eval=1
t0=$(now)
if [ $have_eval = 1 ]; then
  say "eval: $ntest test views x 5 methods"
  lp=()
  [ -n "${TABLE1_LPIPS:-}" ] && lp=(--lpips "$TABLE1_LPIPS")
  [ -n "$lpips_src" ] || say "eval: no LPIPS weights ($lpips_cached is absent: run make weights); LPIPS is n/a"
  for m in $methods; do
    $tool eval --pred "$out/methods/$m" --target "$out/methods/gt" --mask "$out/methods/mask" --json "$out/eval_$m.json" \
      "${lp[@]}" >>"$log" 2>&1 || die "eval: $(tail -n 1 "$log") (log: $log)"
  done
fi
stage_s[eval]=$(secs "$t0" "$(now)")

# ---- report -----------------------------------------------------------------------------------
grid_imgs=()
for v in $(ls "$out/methods/gt" | head -n 4); do
  grid_imgs+=("$out/methods/gt/$v" "$out/methods/input13k/$v" "$out/methods/pervertex13k/$v" "$out/methods/textured13k/$v"
    "$out/methods/smplpix13k/$v")
done
"$helper" grid --out "$out/table1.png.tmp.png" --cols 5 "${grid_imgs[@]}" >>"$log" 2>&1 || die "grid: $(tail -n 1 "$log") (log: $log)"

metric() { # metric FILE KEY: the mean of KEY from an eval JSON, or "—"
  [ -f "$1" ] || { echo "—"; return; }
  jq -r --arg k "$2" '.[$k] | if type == "number" then (. * 1000 | round / 1000 | tostring) else empty end' "$1" 2>/dev/null |
    head -n 1 | grep . || echo "—"
}
ms() { [ -n "${t_frames[$1]:-}" ] && printf '%.0f' "$(calc "${t_frames[$1]} * 1000 / ${n_frames[$1]}")" || echo "—"; }
total=$(secs "$t_start" "$(now)")
stage_name="stage 1 (l1, ${STEPS} steps)"
[ $gan = 1 ] && stage_name="stage 1 + 2 (l1 ${STEPS} steps, then l1+gan ${GANSTEPS} steps: offline variant, no VGG)"
md=$out/TABLE1.md.tmp
{
  echo "# Table 1 on synthetic scanned people ($mode run)"
  echo
  echo "The paper's Table 1 (SMPLpix vs mesh rasterization) reproduced on \`smplpix synth\` subjects: every"
  echo "method renders the same $ntest test views of $((SUBJECTS - NTRAIN)) unseen subjects, in poses and from cameras"
  echo "never seen in training. Scores from \`smplpix eval\` (mean over the test views), full image and inside"
  echo "the subject's mask. Time per frame: wall time of one CLI call per frame (process start, OpenCL set-up"
  echo "and file I/O included; SMPLpix = projection + network)."
  echo
  echo "| method | vertices | PSNR full | SSIM full | LPIPS full | PSNR mask | SSIM mask | time/frame (ms) |"
  echo "|---|---|---|---|---|---|---|---|"
  row() { # row LABEL VERTS METHOD TIMEKEY
    local j=$out/eval_$3.json
    echo "| $1 | $2 | $(metric "$j" psnr) | $(metric "$j" ssim) | $(metric "$j" lpips) | $(metric "$j" psnr_masked) | $(metric "$j" ssim_masked) | $4 |"
  }
  row "per-vertex colours, rasterized (paper: NMR per-verts)" "13,380" pervertex13k "$(ms raster13k)"
  row "per-vertex colours, rasterized (paper: NMR per-verts)" "53,514 (1 Loop step; paper: 27k)" pervertex53k "$(ms raster53k)"
  row "full texture baked from the scan, rasterized (paper: NMR full textures)" "13,380" textured13k "$(ms textured)"
  row "SMPLpix, $stage_name" "13,380" smplpix13k "$(printf '%s + %s' "$(ms project13k)" "$(ms unet13k)")"
  row "SMPLpix, $stage_name" "53,514 (1 Loop step; paper: 27k)" smplpix53k "$(printf '%s + %s' "$(ms project53k)" "$(ms unet53k)")"
  echo
  if [ $have_eval = 1 ]; then
    pv=$(metric "$out/eval_pervertex13k.json" psnr) tx=$(metric "$out/eval_textured13k.json" psnr)
    sp=$(metric "$out/eval_smplpix13k.json" psnr)
    awk -v pv="$pv" -v tx="$tx" -v sp="$sp" 'BEGIN {
      if (pv == "—" || tx == "—" || sp == "—") { print "Goal: not evaluated (a PSNR is missing)."; exit }
      d1 = sp - pv; d2 = tx - sp
      printf "Goal (issue 15), 13,380 vertices, full-image PSNR: SMPLpix - per-vertex = %+.2f dB (goal >= +2: %s); ", d1, (d1 >= 2 ? "met" : "not met")
      printf "textured - SMPLpix = %+.2f dB (goal <= 0.5: %s).\n", d2, (d2 <= 0.5 ? "met" : "not met") }'
  fi
  [ $have_eval = 1 ] || echo "**No scores: \`smplpix eval\` is not in this build (branch h/eval not merged); the images are in $out/methods.**"
  [ $gan = 1 ] || echo "**Stage 2 (l1+gan) not run: \`smplpix train\` has no --loss l1+gan in this build (branch h/recipe not merged).**"
  echo
  echo "## Setup"
  echo
  echo "- Data: \`smplpix synth --subjects $SUBJECTS --views $VIEWS --seed $SEED --size $SIZE --texture-size $SYNTEX\`; subjects 0..$((NTRAIN - 1)) train"
  echo "  (views 0..$((VTRAIN - 1)); view $VTRAIN of each is the validation set), subjects $NTRAIN..$((SUBJECTS - 1)) test (views $VTRAIN..$((VIEWS - 1)))."
  echo "  BVH frames of the training views: $train_frames (plus rest poses); of the test views: $test_frames;"
  echo "  test pose sources also used in training: $overlap."
  echo "- Registration: a $POINTS-point coloured cloud sampled from each scan (\`table1_tool sample\`), \`smplpix register\`"
  echo "  (rigid, pose, free); the registered vertices and colours are reposed to each view's pose"
  echo "  (\`smplpix repose --pose synth.json --view NAME\`), at 13,380 vertices and after one Loop step (53,514;"
  echo "  the paper's 27k row is one subdivision of its 7k body). Texture: \`smplpix bake\` (${TEX}x${TEX})."
  if [ -n "$lpips_src" ]; then
    echo "- LPIPS: v0.1 AlexNet as the \`lpips\` package computes it (\`smplpix eval\`), weights $lpips_src"
    echo "  ($([ "$lpips_src" = "$lpips_cached" ] && echo 'from `make weights`' || echo 'TABLE1_LPIPS'))."
  else
    echo "- LPIPS: not measured (no weights: \`make weights\` puts them in $lpips_cached)."
  fi
  echo "- Rasterizers: \`smplpix raster --aa 2\` (2x2 supersampling, as NMR and the synth photos), unlit colours."
  echo "- Network: UNet width $WIDTH, batch $BATCH, Adam lr 2e-3, $STEPS steps of l1$([ $gan = 1 ] && echo ", then $GANSTEPS of l1+gan at lr 2e-4, PatchGAN width $DISCW"); seed $SEED."
  echo "- Time per stage (s): $(for k in synth register bake inputs train13k train53k eval; do printf '%s %.0f, ' "$([ $k = inputs ] && echo 'inputs+rasterizers' || echo $k)" "${stage_s[$k]:-0}"; done)total $(printf '%.0f' "$total")."
  echo "- Machine: $(uname -srm), $(nproc) CPU cores ($(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ *//')), OpenCL device: $($tool devices 2>/dev/null | head -n 1 | sed 's/^ *//')."
  echo "- Command: \`$([ $mode = quick ] && echo 'TABLE1_QUICK=1 ')make table1\`, $(date -u '+%Y-%m-%d %H:%M UTC'); grid: table1.png (rows: test views;"
  echo "  columns: ground truth | input projection | per-vertex raster | textured raster | SMPLpix, 13k)."
} >"$md"
mv "$out/table1.png.tmp.png" "$report/table1.png"
mv "$md" "$report/TABLE1.md"
say "wrote $report/TABLE1.md and $report/table1.png in $(printf '%.0f' "$total") s"
