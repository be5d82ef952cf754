#!/usr/bin/env python3
"""Reference safetensors files for tests/test_io_safetensors.c, written with the official
`safetensors` Python package (pip install safetensors numpy).

  make_st.py            write ref.safetensors next to this script
  make_st.py --check F  load F (e.g. written by spx_st_save) with the official loader and
                        check it holds exactly what tests/test_io_safetensors.c writes
"""
import os
import sys

import numpy as np
from safetensors.numpy import load_file, save_file
from safetensors import safe_open


def reference():
    return {
        "f32": (np.arange(6, dtype=np.float32).reshape(2, 3) * 0.5 - 1.0),
        "f64": np.array([1.5, -2.25], dtype=np.float64),
        "f16": np.array([1.0, 0.5, -2.0, 65504.0], dtype=np.float16),
        "i64": np.array([-(2 ** 40), 7], dtype=np.int64),
        "i32": np.array([[-3], [4]], dtype=np.int32),
        "i8": np.array([-128, 127], dtype=np.int8),
        "u8": np.array([0, 255, 3], dtype=np.uint8),
        "bool": np.array([True, False, True]),
        "u32": np.array([4000000000], dtype=np.uint32),
        "u64": np.array([2 ** 63 + 5], dtype=np.uint64),
        "scalar": np.array(3.0, dtype=np.float32),
        "empty": np.zeros((0, 3), dtype=np.float32),
        "down1.maxpool_conv.1.double_conv.0.weight": np.full((2, 1, 3, 3), 0.25, dtype=np.float32),
    }


META = {"format": "pt", "note": "smplpix test"}


def check(path):
    """What test_io_safetensors.c writes in test_python_interop (kept in sync by hand)."""
    got = load_file(path)
    want = {
        "w": np.arange(24, dtype=np.float32).reshape(2, 3, 4) / 8.0,
        "b": np.array([-1, 0, 1], dtype=np.int64),
        "h": np.array([0.5, -0.25], dtype=np.float16),
        "m": np.array([True, False]),
        "s": np.array(42, dtype=np.uint8),
    }
    assert set(got) == set(want), (sorted(got), sorted(want))
    for k, v in want.items():
        assert got[k].dtype == v.dtype and got[k].shape == v.shape, (k, got[k].dtype, got[k].shape)
        assert np.array_equal(got[k], v), k
    with safe_open(path, framework="np") as f:
        assert f.metadata() == {"creator": "smplpix", "step": "17"}, f.metadata()
    print("ok: %s loads with safetensors and matches" % path)


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--check":
        check(sys.argv[2])
        return
    out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "ref.safetensors")
    save_file(reference(), out, metadata=META)
    back = load_file(out)
    assert all(np.array_equal(back[k], v) for k, v in reference().items())
    print("wrote", out)


if __name__ == "__main__":
    main()
