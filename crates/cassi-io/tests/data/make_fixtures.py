#!/usr/bin/env python3
"""Generate the tiny test fixtures of cassi-io (run from anywhere):

    /work/pyref/bin/python crates/cassi-io/tests/data/make_fixtures.py

Every array whose axis order matters holds distinct values per element
(value = 100*i + 10*j + k for index (i, j, k)) so that a transposed read fails
the tests. Needs numpy, scipy and h5py. Rerunning rewrites the same array
content (the .mat headers carry a fixed date; zip member times in the .npz and
HDF5 group times may differ).

    make_fixtures.py --check-mat FILE VAR R C B
        loads FILE with scipy.io.loadmat and checks that VAR is a float32 array of
        shape (R, C, B) holding 100*r + 10*c + b (used by the Rust test that
        writes a .mat and asks SciPy to read it back).
"""

import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def idx3(shape, dtype=np.float64):
    i, j, k = np.indices(shape)
    return (100 * i + 10 * j + k).astype(dtype)


def v5_variables():
    return {
        "d": np.array([[1.0, 2.0, 3.0], [4.0, 5.5, 6.0]]),
        "s": np.array([[0.5, 1.0, 1.5], [2.0, 2.5, -3.0]], dtype=np.float32),
        "u8": np.array([[0, 1, 2], [200, 254, 255]], dtype=np.uint8),
        "u16": np.array([[0, 1, 2], [1000, 40000, 65535]], dtype=np.uint16),
        "lg": np.array([[True, False, True], [False, True, False]]),
        "i16": np.array([[-300, 2], [7, 32767]], dtype=np.int16),
        "i32": np.array([[-70000, 2], [7, 123456]], dtype=np.int32),
        # MATLAB (rows, cols, bands) = (4, 5, 3), value 100*r + 10*c + b
        "cube": idx3((4, 5, 3)),
        # band-first (bands, rows, cols) = (3, 8, 9), value 100*b + 10*r + c
        "cube_brc": idx3((3, 8, 9), np.float32),
        "z": np.array([[1 + 2j, 3 - 1j]]),
        "txt": "hello",
        "st": {"a": np.array([[1.0]]), "b": "x"},
    }


def write_v5():
    import scipy.io as sio

    var = v5_variables()
    sio.savemat(os.path.join(HERE, "v5_types.mat"), var, do_compression=False)
    sio.savemat(os.path.join(HERE, "v5_types_compressed.mat"), var, do_compression=True)
    # Only the classes the `matfile` crate (our test oracle) can parse.
    plain = {k: var[k] for k in ("d", "s", "u8", "u16", "lg", "i16", "cube", "cube_brc")}
    sio.savemat(os.path.join(HERE, "v5_plain.mat"), plain, do_compression=False)
    sio.savemat(os.path.join(HERE, "v5_plain_compressed.mat"), plain, do_compression=True)
    # exactly one numeric variable (plus a char one that must be ignored)
    sio.savemat(
        os.path.join(HERE, "v5_one_numeric.mat"),
        {"mask": idx3((4, 6, 1))[:, :, 0] / 1000.0, "note": "a mask"},
    )
    nan = np.zeros((3, 4), dtype=np.float32)
    nan[1, 2] = np.nan
    sio.savemat(os.path.join(HERE, "v5_nan.mat"), {"meas": nan})
    # truncated copies: cut inside the data of the last variable
    for src, dst in [
        ("v5_types.mat", "truncated_v5.mat"),
        ("v5_types_compressed.mat", "truncated_v5_compressed.mat"),
    ]:
        raw = open(os.path.join(HERE, src), "rb").read()
        with open(os.path.join(HERE, dst), "wb") as f:
            f.write(raw[: len(raw) * 2 // 3])
    fix_header_dates()


def fix_header_dates():
    """scipy writes the current date into the 116-byte header text; pin it."""
    text = b"MATLAB 5.0 MAT-file Platform: posix, Created on: Thu Jan  1 00:00:00 2026"
    for name in os.listdir(HERE):
        if not name.endswith(".mat") or name.startswith("v73") or "v73" in name:
            continue
        path = os.path.join(HERE, name)
        raw = bytearray(open(path, "rb").read())
        if raw[:10] != b"MATLAB 5.0":
            continue
        raw[:116] = text.ljust(116, b" ")
        open(path, "wb").write(bytes(raw))


def matlab_v73_header():
    text = (
        b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Thu Jan  1 00:00:00 2026 "
        b"HDF5 schema 1.00 ."
    ).ljust(116, b" ")
    return text + b"\x00" * 8 + b"\x00\x02" + b"IM"


def write_v73(path, with_extras=True):
    """A MAT-file v7.3 as MATLAB writes it: 512-byte user block holding the
    MATLAB header, then HDF5; arrays stored transposed (MATLAB is column-major,
    HDF5 row-major) with a MATLAB_class attribute."""
    import h5py

    def put(f, name, arr, cls, int_decode=None):
        ds = f.create_dataset(name, data=np.ascontiguousarray(arr.T), track_times=False)
        ds.attrs.create("MATLAB_class", np.bytes_(cls))
        if int_decode is not None:
            ds.attrs.create("MATLAB_int_decode", np.int32(int_decode))

    with h5py.File(path, "w", userblock_size=512, libver="earliest") as f:
        put(f, "cube", idx3((4, 5, 3)), "double")
        put(f, "mask", (idx3((4, 6, 1))[:, :, 0] / 1000.0).astype(np.float32), "single")
        if with_extras:
            put(f, "lg", np.array([[1, 0, 1], [0, 1, 0]], dtype=np.uint8), "logical", 1)
            put(f, "u16", np.array([[0, 1, 2], [1000, 40000, 65535]], dtype=np.uint16), "uint16")
            txt = np.array([[ord(c) for c in "hello"]], dtype=np.uint16)
            put(f, "txt", txt, "char", 2)
            g = f.create_group("st")
            g.attrs.create("MATLAB_class", np.bytes_("struct"))
            put(g, "a", np.array([[1.0]]), "double")
    with open(path, "r+b") as fh:
        fh.write(matlab_v73_header())


def write_v73_all():
    write_v73(os.path.join(HERE, "v73.mat"))
    raw = open(os.path.join(HERE, "v73.mat"), "rb").read()
    with open(os.path.join(HERE, "truncated_v73.mat"), "wb") as f:
        f.write(raw[: len(raw) // 2])


def write_npy():
    c = idx3((3, 4, 5))  # (bands, rows, cols) = 100*b + 10*r + c
    np.save(os.path.join(HERE, "cube_f32_c.npy"), c.astype(np.float32))
    np.save(os.path.join(HERE, "cube_f32_f.npy"), np.asfortranarray(c.astype(np.float32)))
    np.save(os.path.join(HERE, "cube_f64_c.npy"), c)
    np.save(os.path.join(HERE, "cube_f64_f.npy"), np.asfortranarray(c))
    np.save(os.path.join(HERE, "cube_f32_be.npy"), c.astype(">f4"))
    # (rows, cols, bands) = (8, 9, 3): the last axis is clearly spectral
    np.save(os.path.join(HERE, "cube_rcb_f32.npy"), idx3((8, 9, 3), np.float32))
    f2 = idx3((4, 5, 1))[:, :, 0]
    np.save(os.path.join(HERE, "frame_u8.npy"), f2.astype(np.uint8))
    np.save(os.path.join(HERE, "frame_u16.npy"), (f2 * 100).astype(np.uint16))
    np.save(os.path.join(HERE, "frame_bool.npy"), (f2.astype(np.int64) % 3) == 0)
    np.save(os.path.join(HERE, "frame_1xhxw.npy"), f2[None, :, :].astype(np.float32))
    np.save(os.path.join(HERE, "vector.npy"), np.arange(6, dtype=np.float32))
    nan = np.zeros((3, 4), dtype=np.float32)
    nan[1, 2] = np.nan
    np.save(os.path.join(HERE, "frame_nan.npy"), nan)
    inf = np.ones((2, 3, 4), dtype=np.float32)
    inf[1, 2, 3] = -np.inf
    np.save(os.path.join(HERE, "cube_inf.npy"), inf)
    raw = open(os.path.join(HERE, "cube_f32_c.npy"), "rb").read()
    with open(os.path.join(HERE, "truncated.npy"), "wb") as f:
        f.write(raw[: len(raw) - 37])


def write_npz():
    c = idx3((3, 4, 5), np.float32)
    arrays = {
        "cube": c,
        "mask": idx3((4, 5, 1))[:, :, 0],
        "amb": idx3((3, 8, 3), np.float32),  # first and last axis both small
    }
    np.savez(os.path.join(HERE, "arrays.npz"), **arrays)
    np.savez_compressed(os.path.join(HERE, "arrays_compressed.npz"), **arrays)
    np.savez(os.path.join(HERE, "single.npz"), measurement=idx3((4, 5, 1))[:, :, 0])


def write_garbage():
    rng = np.random.default_rng(12345)
    junk = rng.integers(0, 256, size=700, dtype=np.uint8).tobytes()
    for name in ("garbage.mat", "garbage.npy", "garbage.npz"):
        with open(os.path.join(HERE, name), "wb") as f:
            f.write(junk)


def check_mat(path, var, r, c, b):
    import scipy.io as sio

    d = sio.loadmat(path)
    a = d[var]
    assert a.dtype == np.float32, a.dtype
    assert a.shape == (r, c, b), a.shape
    assert np.array_equal(a, idx3((r, c, b), np.float32)), "values differ"
    print(f"scipy.io.loadmat OK: {var} {a.shape} {a.dtype}")


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--check-mat":
        _, _, path, var, r, c, b = sys.argv
        check_mat(path, var, int(r), int(c), int(b))
        return
    write_v5()
    write_v73_all()
    write_npy()
    write_npz()
    write_garbage()
    total = 0
    for name in sorted(os.listdir(HERE)):
        if name.endswith(".py"):
            continue
        size = os.path.getsize(os.path.join(HERE, name))
        total += size
        print(f"{size:7d}  {name}")
    print(f"{total:7d}  total")


if __name__ == "__main__":
    main()
