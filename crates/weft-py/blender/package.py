"""Packages the Blender add-on: weft_blender/ with the `weft` wheel unpacked into its
vendor/ folder, as one zip that Blender installs (Edit > Preferences > Add-ons > Install).

usage: python3 package.py WHEEL OUT.zip
"""

import pathlib
import sys
import zipfile


def main(wheel, out):
    here = pathlib.Path(__file__).resolve().parent / "weft_blender"
    out = pathlib.Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".zip.tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
        for f in sorted(here.rglob("*")):
            if f.is_file() and "__pycache__" not in f.parts:
                z.write(f, pathlib.Path("weft_blender") / f.relative_to(here))
        with zipfile.ZipFile(wheel) as w:
            for name in w.namelist():
                # the package itself; its .dist-info is of no use inside Blender
                if name.startswith("weft/"):
                    z.writestr(f"weft_blender/vendor/{name}", w.read(name))
    tmp.replace(out)
    print(f"wrote {out}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
