"""Reads Weft's .vdb files with OpenVDB itself (pyopenvdb, Debian's python3-openvdb) and checks
them against what the Rust test expects (tests/fields.rs writes the expectations as JSON):
grid names, classes, value types, vector types, the transform, the active voxels and the
values at sampled voxels. Exit status 1 on the first mismatch, with what and where."""
import json
import math
import sys

import pyopenvdb as vdb


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def close(a, b, scale, half):
    # f32 (or half) rounding of the written value, plus a floor for values near zero
    # (half floats: their smallest normal, 6.1e-5, of the field's scale).
    if half:
        return abs(a - b) <= 2.0 ** -11 * abs(b) + 6.2e-5 * scale
    return abs(a - b) <= 2.0 ** -23 * abs(b) + 1e-7 * scale


def main(spec_path):
    spec = json.load(open(spec_path))
    checked = 0
    for f in spec["files"]:
        grids, meta = vdb.readAll(f["path"])
        by_name = {g.name: g for g in grids}
        if set(by_name) != set(f["grids"]):
            fail(f"{f['path']}: grids {sorted(by_name)}, expected {sorted(f['grids'])}")
        if not str(meta.get("creator", "")).startswith("Weft"):
            fail(f"{f['path']}: file metadata {meta}")
        nx, ny, nz = f["dims"]
        for name, want in f["grids"].items():
            g = by_name[name]
            where = f"{f['path']}:{name}"
            if g.gridClass != want["class"]:
                fail(f"{where}: class {g.gridClass!r}, expected {want['class']!r}")
            if g.valueTypeName != want["type"]:
                fail(f"{where}: value type {g.valueTypeName!r}, expected {want['type']!r}")
            if g.saveFloatAsHalf != f.get("half", False):
                fail(f"{where}: saveFloatAsHalf {g.saveFloatAsHalf}")
            if "vector_type" in want and g.vectorType != want["vector_type"]:
                fail(f"{where}: vector type {g.vectorType!r}")
            vs = g.transform.voxelSize()
            if any(abs(v - f["voxel_size"]) > 1e-15 for v in vs):
                fail(f"{where}: voxel size {vs}, expected {f['voxel_size']}")
            o = g.transform.indexToWorld((0, 0, 0))
            if any(abs(a - b) > 1e-12 for a, b in zip(o, f["origin"])):
                fail(f"{where}: voxel (0, 0, 0) at {o}, expected {f['origin']}")
            if g.activeVoxelCount() != nx * ny * nz:
                fail(f"{where}: {g.activeVoxelCount()} active voxels, expected {nx * ny * nz}")
            bbox = g.evalActiveVoxelBoundingBox()
            if tuple(bbox[0]) != (0, 0, 0) or tuple(bbox[1]) != (nx - 1, ny - 1, nz - 1):
                fail(f"{where}: active box {bbox}")
            samples = f["samples"][name]
            values = [s["value"] for s in samples]
            flat = [abs(c) for v in values for c in (v if isinstance(v, list) else [v])]
            scale = max(flat + [1.0])
            acc = g.getConstAccessor()
            for s in samples:
                ijk = tuple(s["ijk"])
                w = g.transform.indexToWorld(ijk)
                if any(abs(a - b) > 1e-12 for a, b in zip(w, s["world"])):
                    fail(f"{where}: voxel {ijk} at {w}, the cell centre is {s['world']}")
                got = acc.getValue(ijk)
                want_v = s["value"]
                got_l = list(got) if isinstance(want_v, list) else [got]
                want_l = want_v if isinstance(want_v, list) else [want_v]
                if not all(close(a, b, scale, f.get("half", False)) for a, b in zip(got_l, want_l)):
                    fail(f"{where}: voxel {ijk} holds {got}, expected {want_v}")
                if not acc.isValueOn(ijk):
                    fail(f"{where}: voxel {ijk} is inactive")
                checked += 1
            outside = (nx, ny, nz)
            if acc.isValueOn(outside):
                fail(f"{where}: voxel {outside} outside the grid is active")
    print(f"OpenVDB {'.'.join(map(str, vdb.LIBRARY_VERSION))} read {len(spec['files'])} files; "
          f"{checked} sampled voxels match")


if __name__ == "__main__":
    main(sys.argv[1])
