#!/usr/bin/env python3
"""Draws a slice of a grid in a .vdb file as a PNG, reading the file with OpenVDB itself
(Debian's python3-openvdb, and numpy): a check of what Weft wrote that does not go through
Weft's memory.

    /usr/bin/python3 tools/vdb_slice.py FILE.vdb OUT.png [--grid speed] [--axis y] [--at 0.5]
                                        [--scale 8] [--max 0]

A scalar grid is drawn as is, a vector grid by its length; dark blue is 0 (or the slice's
minimum when it is negative), yellow --max (0: the slice's largest value). Prints the slice's
size and range."""
import argparse
import struct
import sys
import zlib

import numpy as np
import pyopenvdb as vdb


def colour(t):
    # Dark blue -> teal -> yellow, as output.preview's fluid panel.
    stops = np.array([[20, 24, 82], [33, 145, 140], [253, 231, 37]], dtype=float)
    t = np.clip(t, 0.0, 1.0) * 2.0
    i = np.minimum(t.astype(int), 1)
    f = (t - i)[..., None]
    return (stops[i] * (1 - f) + stops[i + 1] * f).astype(np.uint8)


def write_png(path, rgb):
    h, w, _ = rgb.shape
    raw = b"".join(b"\x00" + rgb[y].tobytes() for y in range(h))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    with open(path, "wb") as f:
        f.write(png)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("file")
    ap.add_argument("out")
    ap.add_argument("--grid", default="speed")
    ap.add_argument("--axis", choices="xyz", default="y")
    ap.add_argument("--at", type=float, default=0.5, help="where along the axis (0..1)")
    ap.add_argument("--scale", type=int, default=8, help="pixels per voxel")
    ap.add_argument("--max", type=float, default=0.0)
    a = ap.parse_args()
    grid = vdb.read(a.file, a.grid)
    (x0, y0, z0), (x1, y1, z1) = grid.evalActiveVoxelBoundingBox()
    dims = (x1 - x0 + 1, y1 - y0 + 1, z1 - z0 + 1)
    vector = grid.valueTypeName.startswith("vec3")
    arr = np.zeros(dims + ((3,) if vector else ()), dtype=np.float32)
    grid.copyToArray(arr, ijk=(x0, y0, z0))
    if vector:
        arr = np.linalg.norm(arr, axis=-1)
    ax = "xyz".index(a.axis)
    k = min(int(a.at * dims[ax]), dims[ax] - 1)
    sl = np.take(arr, k, axis=ax)  # the two remaining axes, in x, y, z order
    lo = min(0.0, float(sl.min()))
    hi = a.max if a.max > 0 else float(sl.max())
    t = (sl - lo) / (hi - lo) if hi > lo else np.zeros_like(sl)
    # First remaining axis to the right, second upwards.
    img = colour(t.T[::-1])
    img = np.repeat(np.repeat(img, a.scale, axis=0), a.scale, axis=1)
    write_png(a.out, img)
    print(f"{a.file}: {a.grid} slice {a.axis} = {k} of {dims}: {sl.shape[0]} x {sl.shape[1]} voxels, "
          f"{float(sl.min()):.6g} .. {float(sl.max()):.6g}; wrote {a.out} ({img.shape[1]} x {img.shape[0]} px)")


if __name__ == "__main__":
    sys.exit(main())
