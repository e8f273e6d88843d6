"""Weft and Blender's cloth side by side on the hanging ribbon (issue 16, item 1: the first
scene of the side-by-side; the cantilever and the hanging square are still to come).

    python3 bench/peers/ribbon.py [--quick] [--blender blender] [--weft target/release/weft] [--out bench-out/peers]

The scene: a near-inextensible ribbon 1.2 m long and 2 cm wide (0.01 kg/m), hung by its end
columns 1 m apart, starting as a V of the right length and settling for 8 s under gravity
with damping. Reference: the catenary's mid-span sag c(cosh(a/c) − 1), 2c sinh(a/c) = L.
Each run's error is |sag − reference| at the last frame; its time is the simulation's wall
time (Blender: its frame changes inside Blender; Weft: the `weft run` process). Sweeps:
resolution (segments along the ribbon) for both, Blender's quality (steps a frame) and
Weft's substeps. Writes OUT/ribbon.csv, the chart OUT/ribbon.svg (error against time,
log–log), and prints the table. Skips Blender, with a message,
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


def chart(rows, ref, path):
    """Error against wall time, log–log, one colour per solver, as a small standalone SVG (no
    plotting library needed): each point is one run, labelled with its segments."""
    pts = [(r[0], r[1], r[2], abs(r[3] - ref), r[4]) for r in rows if r[3] is not None and r[4] > 0]
    if not pts:
        return
    W, H, M = 640, 420, 60
    lx = [math.log10(p[4]) for p in pts]
    ly = [math.log10(max(p[3], 1e-12)) for p in pts]
    x0, x1 = math.floor(min(lx)), math.ceil(max(lx))
    y0, y1 = math.floor(min(ly)), math.ceil(max(ly))
    sx = lambda v: M + (v - x0) / max(x1 - x0, 1) * (W - 2 * M)
    sy = lambda v: H - M - (v - y0) / max(y1 - y0, 1) * (H - 2 * M)
    colour = {"weft": "#1f77b4", "blender": "#ff7f0e"}
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="11">',
           f'<rect width="{W}" height="{H}" fill="white"/>',
           f'<text x="{W / 2}" y="20" text-anchor="middle" font-size="13">hanging ribbon: error against wall time</text>']
    for e in range(x0, x1 + 1):
        out.append(f'<line x1="{sx(e)}" y1="{M}" x2="{sx(e)}" y2="{H - M}" stroke="#ddd"/>')
        out.append(f'<text x="{sx(e)}" y="{H - M + 15}" text-anchor="middle">1e{e} s</text>')
    for e in range(y0, y1 + 1):
        out.append(f'<line x1="{M}" y1="{sy(e)}" x2="{W - M}" y2="{sy(e)}" stroke="#ddd"/>')
        out.append(f'<text x="{M - 5}" y="{sy(e) + 4}" text-anchor="end">1e{e} m</text>')
    for solver, n, setting, err, secs in pts:
        x, y = sx(math.log10(secs)), sy(math.log10(max(err, 1e-12)))
        out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{colour.get(solver, "gray")}"><title>{solver} {n} segments, {setting}: {err:.2e} m in {secs:.2f} s</title></circle>')
        out.append(f'<text x="{x + 6:.1f}" y="{y - 4:.1f}" fill="{colour.get(solver, "gray")}" font-size="9">{n}</text>')
    for k, (name, c) in enumerate(colour.items()):
        out.append(f'<circle cx="{W - M - 80}" cy="{M + 10 + 16 * k}" r="4" fill="{c}"/><text x="{W - M - 70}" y="{M + 14 + 16 * k}">{name}</text>')
    out.append("</svg>")
    pathlib.Path(path).write_text("\n".join(out))


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
    chart(rows, ref, out / "ribbon.svg")
    print(f"catenary sag {ref:.6f} m; {FRAMES} frames at 24 fps; chart: {out / 'ribbon.svg'}")
    print("| solver | segments | setting | sag [m] | error [m] | wall [s] |")
    print("|---|---:|---|---:|---:|---:|")
    for solver, n, setting, sag, s, err in rows:
        if sag is None:
            print(f"| {solver} | {n} | {setting} | failed: {err} | | {s:.2f} |")
        else:
            print(f"| {solver} | {n} | {setting} | {sag:.6f} | {abs(sag - ref):.2e} | {s:.2f} |")


if __name__ == "__main__":
    main()
