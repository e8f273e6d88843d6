"""Opens a .usda Weft wrote with the reference USD library (usd-core) and checks it against
what tests/fields.rs expects: no validator errors, curve widths, per-frame velocities, and a
Volume of OpenVDBAssets whose file paths resolve to the VDB files written. Exit status 1 on the
first mismatch."""
import json
import os
import sys

from pxr import Usd, UsdGeom, UsdValidation, UsdVol


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def main(spec_path):
    spec = json.load(open(spec_path))
    stage = Usd.Stage.Open(spec["usda"])
    if not stage:
        fail(f"cannot open {spec['usda']}")
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    if errors:
        fail("validators: " + "; ".join(e.GetMessage() for e in errors))
    for path, want in spec["curves"].items():
        curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(path))
        widths = curves.GetWidthsAttr().Get()
        if widths is None or len(widths) != 1 or abs(widths[0] - want["width"]) > 1e-9:
            fail(f"{path}: widths {widths}, expected [{want['width']}]")
        if curves.GetWidthsInterpolation() != UsdGeom.Tokens.constant:
            fail(f"{path}: widths interpolation {curves.GetWidthsInterpolation()}")
    checked = 0
    for name, frames in spec["velocities"].items():
        prim = UsdGeom.PointBased(stage.GetPrimAtPath(f"/World/{name}"))
        if not prim:
            fail(f"/World/{name} is not a point-based prim")
        for frame, want in frames.items():
            got = prim.GetVelocitiesAttr().Get(Usd.TimeCode(float(frame)))
            if got is None or len(got) != len(want):
                fail(f"{name} frame {frame}: velocities {got}")
            for g, w in zip(got, want):
                if any(abs(a - b) > 2.0 ** -23 * abs(b) + 1e-12 for a, b in zip(g, w)):
                    fail(f"{name} frame {frame}: velocity {g}, expected {w}")
                checked += 1
    vol_spec = spec["volume"]
    vol = UsdVol.Volume(stage.GetPrimAtPath(vol_spec["path"]))
    if not vol:
        fail(f"{vol_spec['path']} is not a Volume")
    fields = vol.GetFieldPaths()
    if set(fields) != set(vol_spec["fields"]):
        fail(f"volume fields {sorted(fields)}, expected {sorted(vol_spec['fields'])}")
    for name, data_type in vol_spec["fields"].items():
        asset = UsdVol.OpenVDBAsset(stage.GetPrimAtPath(fields[name]))
        if asset.GetFieldNameAttr().Get() != name:
            fail(f"{name}: fieldName {asset.GetFieldNameAttr().Get()}")
        if asset.GetFieldDataTypeAttr().Get() != data_type:
            fail(f"{name}: fieldDataType {asset.GetFieldDataTypeAttr().Get()}")
        for frame, file in vol_spec["files"].items():
            p = asset.GetFilePathAttr().Get(Usd.TimeCode(float(frame)))
            if p is None or os.path.realpath(p.resolvedPath) != os.path.realpath(file):
                fail(f"{name} frame {frame}: filePath {p} resolves to "
                     f"{p.resolvedPath if p else None}, expected {file}")
    extent = vol.GetExtentAttr().Get(Usd.TimeCode(0.0))
    if extent is None or any(abs(a - b) > 1e-6 for a, b in
                             zip(list(extent[0]) + list(extent[1]), (0, 0, 0, 0.2, 0.2, 0.2))):
        fail(f"volume extent {extent}")
    print(f"USD {'.'.join(map(str, Usd.GetVersion()))}: {len(validators)} validators, no errors; "
          f"{checked} velocities, widths, {len(fields)} fields over {len(vol_spec['files'])} frames match")


if __name__ == "__main__":
    main(sys.argv[1])
