#!/bin/sh
# ctest table1_quick: the `make table1` pipeline (scripts/table1.sh) on bad input (one line naming
# the file, exit 1, no report written), the CLI pieces it added (repose --pose/--view/--subdivide,
# bake) on bad input, then TABLE1_QUICK=1 end to end: it checks the pipeline and its files (the
# table's rows and columns, the grid PNG, one image per method and test view), not the scores.
# Exit 77 (skipped) after the bad-input checks when the build has no `smplpix synth` (and no
# TABLE1_SYNTH=DIR is given: an existing synth output with the quick mode's sizes).
# usage: table1_quick.sh BUILD_DIR TMP_DIR
set -u
build=$1 tmp=$2
tool=$build/smplpix
script=$(cd "$(dirname "$0")/.." && pwd)/scripts/table1.sh
fails=0
fail() { echo "FAIL: $*"; fails=$((fails + 1)); }
rm -rf "$tmp" && mkdir -p "$tmp"

# expect_error NEEDLE CMD...: exit 1, exactly one line on stderr that contains NEEDLE
expect_error() {
  needle=$1
  shift
  "$@" >"$tmp/out.txt" 2>"$tmp/err.txt"
  rc=$?
  lines=$(wc -l <"$tmp/err.txt")
  if [ $rc -ne 1 ] || [ "$lines" -ne 1 ] || ! grep -qF -- "$needle" "$tmp/err.txt"; then
    fail "$* -> exit $rc, $lines stderr lines, want 1 and one line with '$needle': $(cat "$tmp/err.txt")"
  fi
}

# --- the pipeline on bad input ------------------------------------------------------------------
q() { TABLE1_QUICK=1 TABLE1_BUILD=$build TABLE1_OUT=$tmp/run-bad TABLE1_REPORT=$tmp/report-bad "$@"; }
expect_error "$tmp/none/synth.json: no such file" env TABLE1_QUICK=1 TABLE1_BUILD=$build TABLE1_OUT=$tmp/run-bad \
  TABLE1_REPORT=$tmp/report-bad TABLE1_SYNTH=$tmp/none bash "$script"
mkdir -p "$tmp/bad1" && echo '{"subjects": [{"name": "a"}, {"name": "b"}]}' >"$tmp/bad1/synth.json"
expect_error "$tmp/bad1/synth.json: every subject needs" env TABLE1_QUICK=1 TABLE1_BUILD=$build TABLE1_OUT=$tmp/run-bad \
  TABLE1_REPORT=$tmp/report-bad TABLE1_SYNTH=$tmp/bad1 bash "$script"
mkdir -p "$tmp/bad2" && printf '{"subjects": [' >"$tmp/bad2/synth.json"
expect_error "$tmp/bad2/synth.json: not valid JSON" env TABLE1_QUICK=1 TABLE1_BUILD=$build TABLE1_OUT=$tmp/run-bad \
  TABLE1_REPORT=$tmp/report-bad TABLE1_SYNTH=$tmp/bad2 bash "$script"
mkdir -p "$tmp/precious" && touch "$tmp/precious/keep"
expect_error "$tmp/precious: exists and is not a table1 work directory" env TABLE1_QUICK=1 TABLE1_BUILD=$build \
  TABLE1_OUT=$tmp/precious TABLE1_REPORT=$tmp/report-bad bash "$script"
[ -f "$tmp/precious/keep" ] || fail "table1.sh removed a directory that was not its own"
[ -e "$tmp/report-bad/TABLE1.md" ] || [ -e "$tmp/report-bad/table1.png" ] && fail "a failed run left a report"

# --- repose --pose / --view / --subdivide and bake on bad input -------------------------------------
expect_error "$tmp/none.json" "$tool" repose --registration "$tmp/none.json" --pose "$tmp/none2.json" --out "$tmp/x.ply"
for args in "--bvh x.bvh --view v0" "--pose p.json --subdivide 9" "--pose p.json --bvh x.bvh"; do
  # shellcheck disable=SC2086
  "$tool" repose --registration r.json $args --out "$tmp/x.ply" 2>/dev/null
  [ $? -eq 2 ] || fail "repose $args is not a usage error (exit 2)"
done
expect_error "$tmp/none.ply" "$tool" bake --mesh "$tmp/none.ply" --scan "$tmp/none.ply" --out "$tmp/t.png"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n' >"$tmp/tri.obj"
expect_error "$tmp/tri.obj: the scan has no vertex colours" "$tool" bake --mesh "$tmp/tri.obj" --scan "$tmp/tri.obj" --out "$tmp/t.png"
printf 'v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n' >"$tmp/tric.obj"
expect_error "$tmp/tri.obj: no texture coordinates" "$tool" bake --mesh "$tmp/tri.obj" --scan "$tmp/tric.obj" --out "$tmp/t.png"
[ -e "$tmp/t.png" ] && fail "a failed bake wrote $tmp/t.png"
# a textured triangle bakes; every texel of the covered half holds a scan colour
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n' >"$tmp/triuv.obj"
"$tool" bake --mesh "$tmp/triuv.obj" --scan "$tmp/tric.obj" --out "$tmp/t.png" --size 8 >/dev/null || fail "bake of a textured triangle"
[ -s "$tmp/t.png" ] || fail "bake wrote no texture"

# table1_tool (the point-cloud sampler and the grid composer) on bad input, then on good input
helper=$build/benchmarks/table1_tool
expect_error "$tmp/none.ply" "$helper" sample --mesh "$tmp/none.ply" --points 10 --out "$tmp/pc.ply"
expect_error "$tmp/tri.obj: needs triangles and vertex colours" "$helper" sample --mesh "$tmp/tri.obj" --points 10 --out "$tmp/pc.ply"
expect_error "$tmp/none.png" "$helper" grid --out "$tmp/g.png" --cols 2 "$tmp/t.png" "$tmp/none.png"
[ -e "$tmp/pc.ply" ] || [ -e "$tmp/g.png" ] && fail "a failed table1_tool call wrote its output"
"$helper" sample --mesh "$tmp/tric.obj" --points 100 --seed 3 --out "$tmp/pc.ply" | grep -q "100 points" || fail "sample"
"$helper" sample --mesh "$tmp/tric.obj" --points 100 --seed 3 --out "$tmp/pc2.ply" >/dev/null
cmp -s "$tmp/pc.ply" "$tmp/pc2.ply" || fail "sample is not deterministic for a seed"
"$helper" grid --out "$tmp/g.png" --cols 2 --cell 4x4 "$tmp/t.png" "$tmp/t.png" "$tmp/t.png" | grep -q "3 images" || fail "grid"

# --- the pipeline, tiny ----------------------------------------------------------------------------
# TABLE1_SYNTH=DIR (an existing synth output of the quick mode's sizes) runs it without smplpix synth
if [ -z "${TABLE1_SYNTH:-}" ] && ! "$tool" synth --help >/dev/null 2>&1; then
  echo "smplpix synth is not in this build: the end-to-end run is skipped ($fails failures above)"
  [ $fails -eq 0 ] && exit 77
  exit 1
fi
out=$tmp/run report=$tmp/report
TABLE1_QUICK=1 TABLE1_BUILD=$build TABLE1_OUT=$out TABLE1_REPORT=$report bash "$script" >"$tmp/run.txt" || fail "TABLE1_QUICK=1 scripts/table1.sh"
md=$report/TABLE1.md
if [ -f "$md" ]; then
  grep -q '^| method .*PSNR.*LPIPS.*detail full.*LPIPS mask | detail mask' "$md" || fail "$md: no header with PSNR, LPIPS, detail and their masked values"
  nsp=$(grep -c '^| SMPLpix' "$md")
  [ "$nsp" -ge 2 ] && [ $((nsp % 2)) -eq 0 ] || fail "$md: $nsp SMPLpix rows, want the same stages at both vertex counts"
  [ "$(grep -c '^| per-vertex' "$md")" -eq 2 ] || fail "$md: not 2 per-vertex rows"
  [ "$(grep -c '^| full texture' "$md")" -eq 1 ] || fail "$md: no textured row"
  if "$tool" eval --help >/dev/null 2>&1; then
    grep '^| per-vertex\|^| SMPLpix\|^| full' "$md" | awk -F'|' '$4 !~ /^ *[0-9.]+ *$/ {bad = 1} END {exit bad}' ||
      fail "$md: a PSNR cell is not a number"
  fi
  # every renderer's in-process time per frame is a number (SMPLpix: on its final stage's row)
  grep '^| per-vertex\|^| full' "$md" | awk -F'|' '$12 !~ /^ *[0-9.]+ *$/ {bad = 1} END {exit bad}' ||
    fail "$md: a rasterizer's time per frame is not a number"
  [ "$(grep '^| SMPLpix' "$md" | awk -F'|' '$12 ~ /^ *[0-9.]+ *$/' | wc -l)" -eq 2 ] ||
    fail "$md: not one timed SMPLpix row per vertex count"
  grep -q '^Goal, 13k vertices' "$md" && grep -q '^Goal, 53k vertices' "$md" || fail "$md: no goal line per vertex count"
else
  fail "no $md"
fi
# started again with the same settings, the run continues: nothing is trained again and the scores
# are the same
cp "$md" "$tmp/first.md" 2>/dev/null
ls -l --time-style=+%s.%N "$out"/unet*.safetensors >"$tmp/ckpt1.txt" 2>/dev/null
TABLE1_QUICK=1 TABLE1_BUILD=$build TABLE1_OUT=$out TABLE1_REPORT=$report bash "$script" >"$tmp/rerun.txt" 2>&1 ||
  fail "a second TABLE1_QUICK=1 run: $(tail -n 1 "$tmp/rerun.txt")"
grep -q 'continuing' "$tmp/rerun.txt" || fail "a second run did not continue the first"
ls -l --time-style=+%s.%N "$out"/unet*.s*.stage*.safetensors >"$tmp/ckpt2.txt" 2>/dev/null
grep -v 'unet[0-9]*k.safetensors' "$tmp/ckpt1.txt" | cmp -s - "$tmp/ckpt2.txt" || fail "a continued run trained again"
[ "$(grep '^|' "$tmp/first.md" | cut -d'|' -f1-11)" = "$(grep '^|' "$md" | cut -d'|' -f1-11)" ] ||
  fail "a continued run changed the scores"
# another configuration in the same work dir is refused (TABLE1_FRESH=1 would replace it)
expect_error "holds a run with other settings" env TABLE1_QUICK=1 TABLE1_SEEDS="7 8" TABLE1_BUILD=$build TABLE1_OUT=$out \
  TABLE1_REPORT=$tmp/report-other bash "$script"
head -c 8 "$report/table1.png" 2>/dev/null | od -An -c | grep -q 'P   N   G' || fail "$report/table1.png: not a PNG"
n=$(ls "$out/methods/gt" 2>/dev/null | wc -l)
[ "$n" -ge 1 ] || fail "no test views"
for m in pervertex13k pervertex53k textured13k smplpix13k smplpix53k input13k; do
  [ "$(ls "$out/methods/$m" 2>/dev/null | wc -l)" -eq "$n" ] || fail "$m: not $n images"
done
# the framing the synth manifest records is checked against the cameras (TABLE1_CHECK=1 stops after
# the checks): a camera changed, a view without its framing, a box that does not fill its fill, a
# camera of another size; a manifest without any framing (an older synth output) is read as it is
man=$out/synth/synth.json
if jq -e '.framing' "$man" >/dev/null 2>&1; then
  framed() { # framed NAME JQ-EDIT [CAMERA-JQ-EDIT]: a copy of the synth output with the manifest (and v001's camera) edited
    rm -rf "$tmp/$1" && cp -r "$out/synth" "$tmp/$1" && jq "$2" "$man" >"$tmp/$1/synth.json" || fail "framed $1"
    cam=$tmp/$1/$(jq -r '.subjects[0].views[1].camera' "$man")
    [ -z "${3:-}" ] || { jq "$3" "$cam" >"$cam.new" && mv "$cam.new" "$cam"; } || fail "framed $1: camera"
  }
  chk() { env TABLE1_QUICK=1 TABLE1_CHECK=1 TABLE1_BUILD=$build TABLE1_OUT=$tmp/run-frame TABLE1_REPORT=$tmp/report-frame \
    TABLE1_SYNTH=$tmp/$1 bash "$script"; }
  framed fr-cam . '.K[0][0] *= 1.1'
  expect_error "$tmp/fr-cam/synth.json: view s000_v001: its camera s000/cameras/v001.json" chk fr-cam
  framed fr-size . '.width = 64'
  expect_error "does not match the manifest" chk fr-size
  framed fr-missing 'del(.subjects[0].views[1].framing)'
  expect_error "view s000_v001: no framing" chk fr-missing
  framed fr-fill '.subjects[0].views[1].framing.fill -= 0.05'
  expect_error "view s000_v001: its box fills" chk fr-fill
  framed fr-off '.subjects[0].views[1].framing.box[0] += 4 | .subjects[0].views[1].framing.box[2] += 4'
  expect_error "is not centred" chk fr-off
  framed fr-legacy 'del(.framing) | del(.subjects[].views[].framing)'
  chk fr-legacy >"$tmp/legacy.txt" 2>&1 || fail "an older synth output (no framing) is refused: $(tail -n 1 "$tmp/legacy.txt")"
  grep -q 'records none' "$tmp/legacy.txt" || fail "an older synth output: no note that it records no framing"
  [ -e "$tmp/report-frame/TABLE1.md" ] && fail "a framing check wrote a report"
else
  fail "$man: no framing recorded"
fi
# repose --pose/--view with the run's registration: bad pose files are refused, naming the file
reg=$(ls "$out"/subjects/*/reg.json 2>/dev/null | head -n 1)
if [ -n "$reg" ]; then
  printf '{"pose": [0, 1], "trans": [0, 0, 0]}' >"$tmp/pose_short.json"
  expect_error "$tmp/pose_short.json: the top level \"pose\" must be an array" \
    "$tool" repose --registration "$reg" --pose "$tmp/pose_short.json" --out "$tmp/x.ply"
  expect_error "no view named \"nope\"" "$tool" repose --registration "$reg" --pose "$out/synth/synth.json" --view nope --out "$tmp/x.ply"
  [ -e "$tmp/x.ply" ] && fail "a failed repose wrote $tmp/x.ply"
  "$tool" repose --registration "$reg" --pose "$reg" --out "$tmp/self.obj" >/dev/null || fail "repose --pose REG.json"
  grep -q '^vt ' "$tmp/self.obj" || fail "repose: no texture coordinates in $tmp/self.obj"
  "$tool" repose --registration "$reg" --pose "$reg" --subdivide 1 --out "$tmp/sub.ply" | grep -q '(53514 vertices)' ||
    fail "repose --subdivide 1: not 53514 vertices"
else
  fail "no registration in $out/subjects"
fi
[ $fails -eq 0 ] && echo "table1_quick: ok" && exit 0
exit 1
