#!/usr/bin/python3
"""Golden output of the shipped network (tests/test_model_golden.c).

Needs PyTorch (Debian: python3-torch) and NumPy. Run with the system interpreter from the
repository root after data/models/default.safetensors changes:

  /usr/bin/python3 tests/data/models/make_model_golden.py [--model data/models/default.safetensors]

It loads the model (float16 tensors, as `smplpix export --half` writes them) into the PyTorch
"milesial" UNet with load_state_dict(strict=True) -- PyTorch copies the float16 values into the
float32 parameters, i.e. the model after .float() -- runs it in eval mode on
tests/data/models/input_64x48.npy (HxWx4 RGB-D: `smplpix project` of data/body/human_woman.obj
through tests/data/models/camera_64x48.json) and writes

  tests/data/models/default_golden.npy   the output, HxWx3 float32 (what `smplpix render
                                         --input input_64x48.npy --out X.npy` writes)
  tests/data/models/default_golden.json  which model it belongs to (size and FNV-1a 64 of the
                                         file), its width and sigmoid flag, the output's range

Commit both with the model. The test skips while data/models/default.safetensors is absent and
fails, naming this command, when the golden belongs to another model file.

The UNet module is the one of tests/data/unet/make_unet_golden.py (imported from there, so the
tensor names the golden checks are the ones every other PyTorch test uses).
"""

import argparse
import importlib.util
import json
import os
import sys

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, "..", "..", ".."))


def load_unet_module():
    path = os.path.join(HERE, "..", "unet", "make_unet_golden.py")
    spec = importlib.util.spec_from_file_location("make_unet_golden", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def fnv1a64(data):
    h = 0xCBF29CE484222325
    for b in data:
        h ^= b
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def read_meta(path):
    with open(path, "rb") as f:
        n = int.from_bytes(f.read(8), "little")
        header = json.loads(f.read(n))
    return header.get("__metadata__", {})


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", default=os.path.join(ROOT, "data", "models", "default.safetensors"))
    ap.add_argument("--input", default=os.path.join(HERE, "input_64x48.npy"))
    ap.add_argument("--out", default=os.path.join(HERE, "default_golden"))
    a = ap.parse_args()
    if not os.path.isfile(a.model):
        sys.exit("%s: no such file (the shipped network; see data/models/README.md)" % a.model)
    m = load_unet_module()
    raw = open(a.model, "rb").read()
    sd = m.st_load(a.model)
    dtypes = sorted({str(v.dtype) for v in sd.values()})
    sd = {k: torch.from_numpy(v) for k, v in sd.items()}
    w = sd["inc.double_conv.0.weight"].shape[0]
    model = m.UNet(w)
    model.load_state_dict(sd, strict=True)  # float16 -> float32 parameters (the copy casts)
    model.float().eval()
    meta = read_meta(a.model)
    sigmoid = meta.get("smplpix.sigmoid", "0") == "1"
    x = np.load(a.input).astype(np.float32)  # H x W x 4
    if x.ndim != 3 or x.shape[2] != 4:
        sys.exit("%s: expected an HxWx4 RGB-D image, got shape %s" % (a.input, x.shape))
    with torch.no_grad():
        y = model(torch.from_numpy(np.ascontiguousarray(x.transpose(2, 0, 1)[None])))
        if sigmoid:
            y = torch.sigmoid(y)
    y = y[0].numpy().transpose(1, 2, 0).astype(np.float32)
    np.save(a.out + ".npy", np.ascontiguousarray(y))
    info = {
        "model": os.path.relpath(a.model, ROOT),
        "model_bytes": len(raw),
        "model_fnv1a64": "%016x" % fnv1a64(raw),
        "width": int(w),
        "sigmoid": sigmoid,
        "dtypes": dtypes,
        "input": os.path.relpath(a.input, ROOT),
        "output_min": float(y.min()),
        "output_max": float(y.max()),
        "torch": torch.__version__,
    }
    with open(a.out + ".json", "w") as f:
        json.dump(info, f, indent=1)
        f.write("\n")
    print("wrote %s.npy and %s.json (width %d, %s, output %.4f..%.4f)" % (a.out, a.out, w, "/".join(dtypes),
                                                                          y.min(), y.max()))


if __name__ == "__main__":
    main()
