"""safetensors by hand (numpy only), shared by the tools and golden scripts that read or write the
files smplpix loads: tools/*_to_safetensors.py, tests/data/*/make_*_golden.py (through
tests/data/unet/make_unet_golden.py). Tensors are written in the order given, contiguous, little
endian, the JSON header padded with spaces to a multiple of 8 bytes."""
import json
import os
import struct

import numpy as np

DTYPES = {np.dtype("float32"): "F32", np.dtype("float16"): "F16", np.dtype("int64"): "I64"}
NP_OF = {"F32": "<f4", "F16": "<f2", "I64": "<i8", "F64": "<f8", "I32": "<i4", "U8": "u1"}


def st_save(path, tensors, meta=None):
    """tensors: list of (name, numpy array); written in that order, contiguous. The file appears
    whole (written to a temporary next to it, then renamed) or not at all."""
    header, blobs, off = {}, [], 0
    for name, a in tensors:
        a = np.ascontiguousarray(a)
        dt = DTYPES[a.dtype]
        raw = a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes()
        header[name] = {"dtype": dt, "shape": list(a.shape), "data_offsets": [off, off + len(raw)]}
        blobs.append(raw)
        off += len(raw)
    if meta:
        header["__metadata__"] = meta
    h = json.dumps(header, separators=(",", ":")).encode()
    h += b" " * ((8 - len(h) % 8) % 8)
    tmp = "%s.tmp%d" % (path, os.getpid())
    try:
        with open(tmp, "wb") as f:
            f.write(struct.pack("<Q", len(h)))
            f.write(h)
            for b in blobs:
                f.write(b)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def st_load(path):
    """{name: numpy array} of every tensor (the metadata is skipped)."""
    with open(path, "rb") as f:
        data = f.read()
    (n,) = struct.unpack("<Q", data[:8])
    header = json.loads(data[8 : 8 + n])
    base = 8 + n
    out = {}
    for name, d in header.items():
        if name == "__metadata__":
            continue
        b, e = d["data_offsets"]
        a = np.frombuffer(data[base + b : base + e], dtype=NP_OF[d["dtype"]]).reshape(d["shape"])
        out[name] = a.copy()
    return out
