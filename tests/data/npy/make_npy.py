#!/usr/bin/env python3
"""Reference .npy files for tests/test_io_npy.c, written by NumPy itself.

    /usr/bin/python3 tests/data/npy/make_npy.py            # (re)write the files beside this script
    /usr/bin/python3 tests/data/npy/make_npy.py --check F  # load F (written by smplpix) with NumPy

The values are fixed so the C test can check them exactly. ctest never runs NumPy."""
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def save(name, arr, version=None):
    path = os.path.join(HERE, name)
    if version is None:
        np.save(path, arr)
    else:
        with open(path, "wb") as f:
            np.lib.format.write_array(f, arr, version=version)


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--check":
        for p in sys.argv[2:]:
            a = np.load(p)
            print(p, a.dtype.str, a.shape, a.ravel()[:8].tolist())
        return
    save("f4_2x3.npy", (np.arange(6, dtype=np.float32).reshape(2, 3) * 0.5 - 1).astype("<f4"))
    save("f8_3.npy", np.array([1e300, -0.1, 2.0 ** -1074], dtype="<f8"))
    save("u1_3.npy", np.array([0, 1, 255], dtype="u1"))
    save("i4_3.npy", np.array([-2147483648, 0, 2147483647], dtype="<i4"))
    save("i8_3.npy", np.array([-(2 ** 62), 5, 2 ** 53 + 1], dtype="<i8"))
    save("be_f4_3.npy", np.array([1.5, -2.25, 3e-5], dtype=">f4"))
    save("be_i8_2.npy", np.array([-3, 2 ** 40], dtype=">i8"))
    save("f4_0d.npy", np.array(3.25, dtype="<f4"))
    save("f4_2x3x4.npy", np.arange(24, dtype="<f4").reshape(2, 3, 4))
    save("f4_0x3.npy", np.zeros((0, 3), dtype="<f4"))
    save("f2_3.npy", np.array([1.0, -0.5, 65504.0], dtype="<f2"))
    save("b1_3.npy", np.array([True, False, True]))
    save("f4_v2.npy", np.array([7.0, 8.0], dtype="<f4"), version=(2, 0))
    save("fortran_2x2.npy", np.asfortranarray(np.arange(4, dtype="<f4").reshape(2, 2)))


if __name__ == "__main__":
    main()
