"""Weft and Blender's cloth side by side on the hanging ribbon (issue 16, item 1: the first
scene of the side-by-side; the cantilever and the hanging square are still to come).

    python3 bench/peers/ribbon.py [--quick] [--blender blender] [--weft target/release/weft] [--out bench-out/peers]

The scene: a near-inextensible ribbon 1.2 m long and 2 cm wide (0.01 kg/m), hung by its end
columns 1 m apart, starting as a V of the right length and settling for 8 s under gravity
with damping. Reference: the catenary's mid-span sag c(cosh(a/c) − 1), 2c sinh(a/c) = L.
Each run's error is |sag − reference| at the last frame; its time is the simulation's wall
time (Blender: its frame changes inside Blender; Weft: the `weft run` process). Sweeps:
resolution (segments along the ribbon) for both, Blender's quality (steps a frame) and
Weft's substeps. Writes OUT/ribbon.csv and prints the table. Skips Blender, with a message,
where it is not installed. Stdlib only.

Blender runs with its default mass (0.3 kg a vertex) and air damping: the static shape of a
near-inextensible ribbon does not depend on its weight, and with the chain's real 0.3 g a
vertex the default air damping makes Blender's ribbon creep (its sag still drifting after
16 s). Blender's time excludes its start-up; Weft's includes its whole process (start, graph
load, OBJ read), which favours Blender slightly.
"""

import argparse
import csv
import json
import math
import os
import pathlib
import shutil
import subprocess
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
A, L, WIDTH, FRAMES = 0.5, 1.2, 0.02, 192


def catenary_sag():
    lo, hi = 1e-3, 1e3
    for _ in range(200):
        c = 0.5 * (lo + hi)
        if 2 * c * math.sinh(A / c) > L:
            lo = c
        else:
            hi = c
    return c * (math.cosh(A / c) - 1)


def write_ribbon(n, path):
    """A V of length L from x = −A to A (y-up, ends at y = 0), n segments along, 2 rows
    across: vertex 2i + j is column i, row j."""
    depth = math.sqrt((L / 2) ** 2 - A * A)
    with open(path, "w") as f:
        for i in range(n + 1):
            u = 1 - abs(2 * i / n - 1)
            for j in range(2):
                f.write(f"v {-A + 2 * A * i / n!r} {-depth * u!r} {WIDTH * (j - 0.5)!r}\n")
        for i in range(n):
            a = 2 * i + 1  # 1-based
            f.write(f"f {a} {a + 2} {a + 1}\nf {a + 1} {a + 2} {a + 3}\n")


def run_weft(weft, n, substeps, obj, work):
    out = work / f"weft_{n}_{substeps}"
    cmd = [weft, "run", str(HERE / "ribbon.json"), "--frames", f"0..{FRAMES}", "--no-checkpoints",
           "--out", str(out), "--output", "mid",
           "--set", f"clothmesh.path={obj}",
           "--set", f"pins.vertices=[0,1,{2 * n},{2 * n + 1}]",
           "--set", f"mid.index={n}",
           "--set", f"solve.substeps={substeps}"]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if r.returncode != 0:
        return None, seconds, r.stderr.strip().splitlines()[-1]
    last = r.stdout.strip().splitlines()[-1].split("\t")[1]
    return -json.loads(last)[1], seconds, ""


def run_blender(blender, n, quality, stiffness, obj, work):
    out = work / f"blender_{n}_{quality}.json"
    cmd = [blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python",
           str(HERE / "blender_ribbon.py"), "--", str(obj), str(quality), str(stiffness), str(FRAMES), str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0 or not out.exists():
        return None, 0.0, (r.stdout + r.stderr).strip().splitlines()[-1]
    d = json.load(open(out))
    return d["sag"], d["seconds"], ""


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true")
    p.add_argument("--blender", default="blender")
    p.add_argument("--weft", default=str(HERE.parents[1] / "target/release/weft"))
    p.add_argument("--out", default="bench-out/peers")
    a = p.parse_args()
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    ref = catenary_sag()
    sizes = [10, 20] if a.quick else [10, 20, 40, 80]
    blender = shutil.which(a.blender)
    if blender is None:
        print(f"Blender ({a.blender}) is not installed: its runs are skipped")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        work = pathlib.Path(tmp)
        for n in sizes:
            obj = work / f"ribbon_{n}.obj"
            write_ribbon(n, obj)
            for substeps in ([1, 4] if a.quick else [1, 2, 4, 8]):
                sag, s, err = run_weft(a.weft, n, substeps, obj, work)
                rows.append(("weft", n, f"substeps {substeps}", sag, s, err))
            if blender:
                for quality in ([5, 20] if a.quick else [2, 5, 10, 20, 40]):
                    sag, s, err = run_blender(blender, n, quality, 1000.0, obj, work)
                    rows.append(("blender", n, f"quality {quality}", sag, s, err))
    with open(out / "ribbon.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["solver", "segments", "setting", "sag_m", "reference_m", "error_m", "seconds", "failure"])
        for solver, n, setting, sag, s, err in rows:
            e = abs(sag - ref) if sag is not None else ""
            w.writerow([solver, n, setting, sag if sag is not None else "", ref, e, f"{s:.3f}", err])
    print(f"catenary sag {ref:.6f} m; {FRAMES} frames at 24 fps")
    print("| solver | segments | setting | sag [m] | error [m] | wall [s] |")
    print("|---|---:|---|---:|---:|---:|")
    for solver, n, setting, sag, s, err in rows:
        if sag is None:
            print(f"| {solver} | {n} | {setting} | failed: {err} | | {s:.2f} |")
        else:
            print(f"| {solver} | {n} | {setting} | {sag:.6f} | {abs(sag - ref):.2e} | {s:.2f} |")


if __name__ == "__main__":
    main()
