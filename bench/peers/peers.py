"""Weft and Blender's cloth side by side: error against wall time on three scenes with known
answers (issue 16, item 1).

    python3 bench/peers/peers.py [ribbon|cantilever|square ...] [--quick] [--blender blender]
                                 [--weft target/release/weft] [--out bench-out/peers] [--repeat N]

Scenes (all by default):
- ribbon: a near-inextensible ribbon 1.2 m long, 2 cm wide, hung by its end columns 1 m apart,
  settling for 8 s with damping; error = |mid-span sag − the catenary's c(cosh(a/c) − 1)|.
- cantilever: a strip 0.5 m × 0.1 m, 1 mm, E = 2 GPa, ν = 0, 0.2 kg/m², clamped along a
  short edge, settling for 4 s with damping; error = |tip deflection − the elastica's| (the
  heavy cantilever solved exactly, not qL⁴/8EI: the deflection is 18 % of the length).
- square: a 1 m square, horizontal, held at two adjacent corners, falling and swinging for 2 s
  without damping (near-inextensible, soft bending); error = the largest distance, over the
  frames 0.25 s apart, of the cloth's centre of mass from a converged Weft run's (32 × 32
  cells, 64 substeps of BDF2, tolerance 1e-6: about 4 minutes, computed once and kept in
  OUT/square_reference.json; converged to a few centimetres, see BENCHMARKS.md).

Both solvers get the same vertices: Weft as triangles, Blender as the grid's quads (what its
cloth is built for; the ribbon keeps its triangles, as in the first version), except where a
user of each would build the clamp differently (Weft holds one column with clamp: true;
Blender, which has no clamp, pins two columns, the second at the strip's root). Each run's time is the simulation's wall time:
Blender's frame changes after its start frame (where it builds its springs), without its
start-up nor the reading of its vertices; Weft's graph evaluation of the frames after its
start frame (where it compiles the system), from its --stats-json, the process's start and
the graph file's parse left out. Weft reports what is measured from its graph's outputs (one
vertex's position, the centre of mass) without writing files in the timed frames. Each process's whole wall time is in the CSV
too. Sweeps: resolution for both; Weft's substeps, tolerance, method, (on the square)
integrator and (on the ribbon) membrane stiffness; Blender's quality (steps a frame) and membrane stiffness. Blender's stiffnesses come from the material by the formulas of
its source (see `blender_material`), not from fitting its answer to the reference.

Writes OUT/SCENE.csv and OUT/SCENE.svg (error against time, log–log) for every scene and prints
each table; exits 1 when a Weft run fails (a Blender run may: unstable settings are part of its
sweep). Skips Blender, with a message, where it is not installed. Stdlib only.
"""

import argparse
import csv
import json
import math
import pathlib
import shutil
import statistics
import subprocess
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
G = 9.81
FPS = 24


# --- meshes -----------------------------------------------------------------------------------

def grid(nx, ny, lx, ly, x0=0.0, z0=0.0):
    """A horizontal (y = 0) grid of nx × ny cells over [x0, x0 + lx] × [z0, z0 + ly], vertex
    i + (nx + 1) j at column i, row j; diagonals alternating cell by cell (no preferred
    direction, as Weft's geo.grid)."""
    verts = [(x0 + lx * i / nx, 0.0, z0 + ly * j / ny) for j in range(ny + 1) for i in range(nx + 1)]
    faces = []
    for j in range(ny):
        for i in range(nx):
            a, b = i + (nx + 1) * j, i + 1 + (nx + 1) * j
            c, d = a + nx + 1, b + nx + 1
            faces += [(a, b, d), (a, d, c)] if (i + j) % 2 == 0 else [(a, b, c), (b, d, c)]
    return verts, faces


def quads(nx, ny, x0=0.0):
    """The quads of the same grid's cells (vertex i + (nx + 1) j), for Blender, whose cloth
    is built for quad meshes (shear springs on their diagonals, its bending calibrated on
    them; on right triangles its hinge forces are not an energy's gradient: see
    `blender_material`)."""
    return [(i + (nx + 1) * j, i + 1 + (nx + 1) * j, i + 1 + (nx + 1) * (j + 1), i + (nx + 1) * (j + 1))
            for j in range(ny) for i in range(nx)]


def write_obj(verts, faces, path):
    with open(path, "w") as f:
        for v in verts:
            f.write("v {!r} {!r} {!r}\n".format(*v))
        for t in faces:
            f.write("f " + " ".join(str(k + 1) for k in t) + "\n")


# --- Blender's material from physical units ---------------------------------------------------

# Blender's cloth counts time in frames (× its time_scale) whatever the scene's fps, and uses a
# thousandth of the scene's gravity (SIM_cloth_solve, cloth_calc_force in Blender's source).
# With time_scale 1 and the scene's gravity set to 1000 g T² (T = 1/24 s, a frame), one of
# its time units is one frame, as in Weft, and stiffnesses and damping convert by T² and T.
T = 1.0 / FPS
BLENDER_GRAVITY = 1000.0 * G * T * T


def blender_material(et, d, h):
    """Blender 3.4's stiffnesses for a sheet of membrane stiffness E t [N/m] and bending
    stiffness D [N m] on a square quad grid of spacing h, in the time units above. From its
    source (cloth_build_springs, cloth_calc_spring_force, SIM_mass_spring_force_spring_linear
    and _angular), checked by runs of Blender 3.4.1:
    - tension and compression: every edge a spring pulling with (s / l̄)(l − l₀), l̄ the mean
      rest edge length (h); shear: both diagonals of every quad, (s_shear / l̄)(l − l₀), in
      tension only. Edges k and diagonals k/2 make an isotropic lattice with E t = 4k/3 and
      ν = 1/3 (the Cauchy–Born energy of the square lattice), so s = ¾ E t h T².
    - bending: a hinge on every edge with torque 0.1 s_b l_e (θ − θ₀) on each wing; on square
      quads the hinges sum to a plate of D = s_b h² / 20 (measured on a cantilever to 2 %), so
      s_b = 20 D T² / h². Blender applies it without its Jacobian (explicitly inside the
      implicit step), so a stiff sheet needs quality ≳ T √(2 D / ρ_A) / h² to stay stable.
    - mass: per vertex, the same for all (the scene chooses how to spread the sheet's)."""
    s = 0.75 * et * h * T * T
    return {"tension": s, "compression": s, "shear": 0.5 * s, "bending": 20.0 * d * T * T / (h * h)}


def blender_air(c, mass):
    """Blender's air damping for Weft's mass-proportional −c m v: its force is −0.01 a v per
    vertex in its time units (SIM_mass_spring_force_drag), so a = 100 c m T."""
    return 100.0 * c * mass * T


# --- scenes -----------------------------------------------------------------------------------

class Settling:
    """A scene measured once, at its last frame, by how far one vertex (`info["probe"]`) hangs
    below y = 0, against a number."""

    def frames(self):
        return self.FRAMES, [self.FRAMES]

    def measure(self, positions, info):
        return -positions[self.FRAMES][info["probe"]][1]

    def error(self, value, ref):
        return abs(value - ref)


class Ribbon(Settling):
    name, title, unit = "ribbon", "hanging ribbon: |sag − catenary| against wall time", "m"
    A, L, WIDTH, FRAMES = 0.5, 1.2, 0.02, 192

    def sizes(self, quick):
        return [10, 20] if quick else [10, 20, 40, 80, 160]

    def weft_settings(self, quick):
        """The common sweep, and the membrane stiffer (×2, ×10), as Blender's stiffness is
        swept: the ribbon's own stretch under its weight (3e-5 m at E t = 100 kN/m) is part
        of its error at 10 and 20 segments."""
        common = common_weft_settings(quick)
        return common if quick else common + [{"substeps": 1, "membrane": 2}, {"substeps": 1, "membrane": 10}]

    def reference(self, runner):
        lo, hi = 1e-3, 1e3
        for _ in range(200):
            c = 0.5 * (lo + hi)
            if 2 * c * math.sinh(self.A / c) > self.L:
                lo = c
            else:
                hi = c
        return c * (math.cosh(self.A / c) - 1)

    def setup(self, n):
        """A V of length L from x = −A to A (y-up, ends at y = 0), n segments along, 2 rows
        across: vertex 2i + j is column i, row j."""
        depth = math.sqrt((self.L / 2) ** 2 - self.A ** 2)
        verts = []
        for i in range(n + 1):
            u = 1 - abs(2 * i / n - 1)
            verts += [(-self.A + 2 * self.A * i / n, -depth * u, self.WIDTH * (j - 0.5)) for j in range(2)]
        faces = []
        for i in range(n):
            a = 2 * i
            faces += [(a, a + 2, a + 1), (a + 1, a + 2, a + 3)]
        pins = [0, 1, 2 * n, 2 * n + 1]
        # No bending on either side (bend_scale 0 leaves the shell's bending terms out, as
        # Blender's bending 0 does): the catenary is a perfectly flexible chain. Until the
        # nineteenth session Weft's ribbon kept a millionth of the shell's bending stiffness;
        # its sag was the same to three digits at every resolution, and those terms were more
        # than half of each Newton iteration's cost (30 → 13 µs at 10 segments).
        weft = {"verts": verts, "faces": faces, "pins": pins, "clamp": False,
                "set": {"shell.youngs_modulus": 2.0e8, "shell.poisson_ratio": 0.0, "shell.thickness": 5.0e-4,
                        "shell.bend_scale": 0.0, "density.area_density": 0.5, "damping.coefficient": 2.0}}
        # Blender as in its first version of this benchmark: its default mass (0.3 kg a vertex)
        # and air damping, no bending: the static shape of a near-inextensible ribbon does not
        # depend on its weight, and with the chain's real 0.3 g a vertex Blender's air damping
        # makes the ribbon creep (its sag still drifting after 16 s).
        blender = {"verts": verts, "faces": faces, "pins": pins,
                   "material": {"tension": 1000.0, "compression": 1000.0, "shear": 1000.0, "bending": 0.0, "mass": 0.3},
                   "air_damping": 1.0, "spring_damping": 5.0, "bending_damping": 0.5, "pin_stiffness": 1000.0}
        weft["info"] = blender["info"] = {"probe": n}
        return weft, blender


class Cantilever(Settling):
    name, title, unit = "cantilever", "clamped strip: |tip deflection − elastica| against wall time", "m"
    L, W, E, T, RHO_A, DAMPING, FRAMES = 0.5, 0.1, 2.0e9, 1.0e-3, 0.2, 10.0, 96

    def sizes(self, quick):
        return [10, 20] if quick else [10, 20, 40, 80]

    def d(self):
        return self.E * self.T ** 3 / 12  # ν = 0

    def blender_settings(self, n, quick):
        """Blender's bending is explicit: stable from quality ≈ T √(2 D / ρ_A) / h² (22 at 10
        segments, 4× that at each doubling: see `blender_material`), so its qualities are
        multiples of that; at 40 segments (344 steps a frame, a minute a run) two of them, and
        80 segments (about 1400 steps a frame) are left out."""
        stable = math.ceil(T * math.sqrt(2 * self.d() / self.RHO_A) / (self.L / n) ** 2)
        if quick or n > 40:
            return [] if n > 40 else [(stable, 1.0), (4 * stable, 1.0)]
        if n == 40:
            return [(stable, 1.0), (2 * stable, 1.0)]
        return [(max(1, stable // 2), 1.0), (stable, 1.0), (2 * stable, 1.0), (4 * stable, 1.0), (2 * stable, 0.1)]

    def reference(self, runner):
        """The heavy elastica clamped horizontally: EI θ″ = −q (L − s) cos θ, θ(0) = 0,
        θ′(L) = 0, δ = ∫ sin θ ds; shooting on θ′(0) by bisection, RK4 over 4000 steps
        (the same reference as weft-bench's elastica_tip)."""
        ei, q, ln = self.d() * self.W, self.RHO_A * self.W * G, self.L

        def shoot(k0, steps=4000):
            h = ln / steps
            f = lambda s, u: (u[1], -q * (ln - s) * math.cos(u[0]) / ei, math.sin(u[0]))
            u = (0.0, k0, 0.0)
            for i in range(steps):
                s = i * h
                k1 = f(s, u)
                k2 = f(s + h / 2, tuple(u[j] + h / 2 * k1[j] for j in range(3)))
                k3 = f(s + h / 2, tuple(u[j] + h / 2 * k2[j] for j in range(3)))
                k4 = f(s + h, tuple(u[j] + h * k3[j] for j in range(3)))
                u = tuple(u[j] + h / 6 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]) for j in range(3))
            return u

        lo, hi = 0.0, q * ln * ln / ei
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if shoot(mid)[1] > 0 else (mid, hi)
        return shoot(0.5 * (lo + hi))[2]

    def setup(self, n):
        ny = max(2, round(n * self.W / self.L))  # square cells
        h = self.L / n
        verts, faces = grid(n, ny, self.L, self.W)
        held = [(n + 1) * j for j in range(ny + 1)]
        tip = n + (n + 1) * (ny // 2)  # the middle of the tip (ν = 0: the tip edge stays straight)
        weft = {"verts": verts, "faces": faces, "pins": held, "clamp": True,
                "set": {"shell.youngs_modulus": self.E, "shell.poisson_ratio": 0.0, "shell.thickness": self.T,
                        "shell.bend_scale": 1.0, "density.area_density": self.RHO_A,
                        "damping.coefficient": self.DAMPING}}
        # Blender has no clamp: one more column at x = −h, and it and the root column pinned;
        # quads. Its vertices all weigh the same: a column's ny + 1 carry the strip's weight
        # per length h (the load per length its beam needs).
        bverts, _ = grid(n + 1, ny, self.L + h, self.W, x0=-h)
        bheld = [(n + 2) * j + k for j in range(ny + 1) for k in (0, 1)]
        btip = n + 1 + (n + 2) * (ny // 2)
        mass = self.RHO_A * self.W * h / (ny + 1)
        blender = {"verts": bverts, "faces": quads(n + 1, ny), "pins": bheld,
                   "material": dict(blender_material(self.E * self.T, self.d(), h), mass=mass),
                   "air_damping": blender_air(self.DAMPING, mass), "spring_damping": 0.0,
                   "bending_damping": 0.0, "pin_stiffness": 1000.0, "gravity": BLENDER_GRAVITY}
        weft["info"], blender["info"] = {"probe": tip}, {"probe": btip}
        return weft, blender


class Square:
    name, title, unit = "square", "hanging square: centre-of-mass error against wall time", "m"
    SIDE, ET, D, RHO_A, FRAMES = 1.0, 1.0e5, 1.0e-6, 0.15, 48
    REF_N, REF_SUBSTEPS, REF_TOL, REF_INTEGRATOR = 32, 64, 1.0e-6, "bdf2"

    def sizes(self, quick):
        # 2² to 6²: Blender's cheapest runs are its coarsest, so both get them (at 2² and 3²
        # both solvers' cheapest runs reach errors that Blender's 4² runs take longer for).
        return [8, 16] if quick else [2, 3, 4, 6, 8, 16, 24, 32]

    def weft_settings(self, quick):
        """Its error is mostly implicit Euler's numerical damping of the swing (first order in
        the step), so more substeps, BDF2 (second order), and the linearized step (one Newton
        iteration a substep, Blender's scheme) with many of them."""
        if quick:
            return [{"substeps": 1}, {"substeps": 1, "integrator": "bdf2"}]
        return [{"substeps": 1}, {"substeps": 4}, {"substeps": 16},
                {"substeps": 1, "integrator": "bdf2"}, {"substeps": 2, "integrator": "bdf2"},
                {"substeps": 4, "integrator": "bdf2"},
                # The linearized step's error falls fast from 1 to 8 substeps (the swing's
                # damping), so that range is swept densely, as Blender's quality is.
                *({"substeps": k, "method": "linearized"} for k in (1, 2, 3, 4, 5, 6, 8, 16, 64))]

    def setup(self, n):
        verts, faces = grid(n, n, self.SIDE, self.SIDE, x0=-self.SIDE / 2, z0=-self.SIDE / 2)
        pins = [0, n]  # two adjacent corners (z = −SIDE/2)
        t = 5.0e-4
        e = self.ET / t
        # ν = 1/3: what Blender's lattice has (it matters little: the sheet barely stretches).
        weft = {"verts": verts, "faces": faces, "pins": pins, "clamp": False,
                "set": {"shell.youngs_modulus": e, "shell.poisson_ratio": 1.0 / 3.0, "shell.thickness": t,
                        "shell.bend_scale": self.D / (e * t ** 3 / 12 / (1 - 1.0 / 9.0)),
                        "density.area_density": self.RHO_A, "damping.coefficient": 0.0}}
        mass = self.RHO_A * self.SIDE ** 2 / len(verts)
        blender = {"verts": verts, "faces": quads(n, n), "pins": pins,
                   "material": dict(blender_material(self.ET, self.D, self.SIDE / n), mass=mass),
                   "air_damping": 0.0, "spring_damping": 0.0, "bending_damping": 0.0, "pin_stiffness": 1000.0,
                   "gravity": BLENDER_GRAVITY}
        # Weft's centre of mass is its graph's output (the vertices weighted by their lumped
        # rest areas, as its masses); Blender's vertices weigh the same: their mean.
        weft["info"] = {}
        blender["info"] = {"weights": [1.0] * len(verts)}
        return weft, blender

    def frames(self):
        return self.FRAMES, list(range(6, self.FRAMES + 1, 6))

    def measure(self, positions, info):
        w = info["weights"]
        total = sum(w)
        return {f: [sum(w[k] * p[k][c] for k in range(len(w))) / total for c in range(3)]
                for f, p in sorted(positions.items())}

    def error(self, value, ref):
        return max(math.dist(value[f], ref[str(f)] if str(f) in ref else ref[f]) for f in value)

    def reference(self, runner):
        key = {"n": self.REF_N, "substeps": self.REF_SUBSTEPS, "tolerance": self.REF_TOL,
               "integrator": self.REF_INTEGRATOR,
               "et": self.ET, "d": self.D, "rho_a": self.RHO_A, "frames": self.FRAMES}
        path = runner.out / "square_reference.json"
        if path.exists():
            kept = json.load(open(path))
            if kept.get("key") == key:
                return kept["com"]
        print(f"square: computing the reference ({self.REF_N} × {self.REF_N} cells, "
              f"{self.REF_SUBSTEPS} substeps of {self.REF_INTEGRATOR}, tolerance {self.REF_TOL}); kept in {path}")
        value, seconds, err, _ = runner.weft(self, self.REF_N, {"substeps": self.REF_SUBSTEPS,
                                                                 "tolerance": self.REF_TOL,
                                                                 "integrator": self.REF_INTEGRATOR})
        if value is None:
            raise SystemExit(f"square: the reference run failed: {err}")
        com = {str(f): v for f, v in value.items()}
        path.write_text(json.dumps({"key": key, "seconds": seconds, "com": com}))
        return com


SCENES = {s.name: s for s in (Ribbon(), Cantilever(), Square())}


# --- runs -------------------------------------------------------------------------------------

class Runner:
    def __init__(self, args, work, out):
        self.args, self.work, self.out = args, work, out
        self.blender = shutil.which(args.blender)

    def weft(self, scene, n, setting):
        w, _ = scene.setup(n)
        tag = f"{scene.name}_{n}_" + "_".join(f"{k}{v}" for k, v in setting.items())
        obj = self.work / f"{tag}.obj"
        write_obj(w["verts"], w["faces"], obj)
        frames, sample = scene.frames()
        out = self.work / f"weft_{tag}"
        cmd = [self.args.weft, "run", str(HERE / "sheet.json"), "--frames", f"0..{frames}", "--no-checkpoints",
               "--out", str(out), "--set", f"clothmesh.path={obj}",
               "--set", f"pins.vertices={json.dumps(w['pins'])}", "--set", f"pins.clamp={json.dumps(w['clamp'])}"]
        for k, v in w["set"].items():
            cmd += ["--set", f"{k}={json.dumps(v)}"]
        for k, v in setting.items():
            if k == "membrane":
                # The membrane stiffer by v at the same bending stiffness D ∝ E · bend_scale.
                cmd += ["--set", f"shell.youngs_modulus={json.dumps(w['set']['shell.youngs_modulus'] * v)}",
                        "--set", f"shell.bend_scale={json.dumps(w['set']['shell.bend_scale'] / v)}"]
            else:
                cmd += ["--set", f"solve.{k}={v}"]
        # One vertex at the last frame, or the centre of mass at every frame, is an output: no
        # files written in the timed frames (writing each frame's mesh, though its own time
        # is left out, slowed the 4² square's solver by half: the fsyncs' waits leave its
        # caches cold).
        probe = w["info"].get("probe")
        cmd += (["--output", "com"] if probe is None
                else ["--set", f"probe.index={probe}", "--output", "probe"])
        cmd += ["--stats-json", str(out / "stats.json")]
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            return None, wall, (r.stderr.strip().splitlines() or ["failed"])[-1], wall
        # Like Blender's frame changes after its start frame: the graph's evaluation of every
        # frame after the first (the first compiles the system, as Blender's start frame
        # builds its springs, outside its timing), without output nodes' share (none is
        # asked for), the process's start and the graph file's parse.
        stats = json.load(open(out / "stats.json"))
        seconds = sum(f["seconds"] - f["output_seconds"] for f in stats["frames"][1:])
        rows = {int(line.split("\t")[0]): json.loads(line.split("\t")[1])
                for line in r.stdout.strip().splitlines()[1:]}
        shutil.rmtree(out, ignore_errors=True)
        if probe is None:
            return {f: rows[f] for f in sample}, seconds, "", wall
        return scene.measure({frames: {probe: rows[frames]}}, w["info"]), seconds, "", wall

    def blender_run(self, scene, n, quality, stiffness):
        _, b = scene.setup(n)
        tag = f"{scene.name}_{n}_{quality}_{stiffness}"
        obj = self.work / f"blender_{tag}.obj"
        write_obj(b["verts"], b["faces"], obj)
        frames, sample = scene.frames()
        mat = dict(b["material"])
        for k in ("tension", "compression", "shear"):
            mat[k] *= stiffness
        cfg = dict(mat, obj=str(obj), pins=b["pins"], quality=quality, frames=frames, sample=sample,
                   air_damping=b["air_damping"], spring_damping=b["spring_damping"],
                   bending_damping=b["bending_damping"], pin_stiffness=b["pin_stiffness"],
                   **({"gravity": b["gravity"]} if "gravity" in b else {}),
                   out=str(self.work / f"blender_{tag}.json"))
        cfg_path = self.work / f"blender_{tag}.cfg.json"
        cfg_path.write_text(json.dumps(cfg))
        cmd = [self.blender, "-b", "--factory-startup", "--python-exit-code", "1", "--python",
               str(HERE / "blender_cloth.py"), "--", str(cfg_path)]
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0 or not pathlib.Path(cfg["out"]).exists():
            return None, 0.0, ((r.stdout + r.stderr).strip().splitlines() or ["failed"])[-1], wall
        d = json.load(open(cfg["out"]))
        positions = {int(f): p for f, p in d["positions"].items()}
        return scene.measure(positions, b["info"]), d["seconds"], "", wall


def weft_settings(scene, quick):
    """solver.solid settings swept; a scene may choose its own."""
    if hasattr(scene, "weft_settings"):
        return scene.weft_settings(quick)
    return common_weft_settings(quick)


def common_weft_settings(quick):
    """The settings every scene sweeps unless it chooses its own ("membrane": the membrane
    stiffness multiplied, see `Runner.weft`)."""
    if quick:
        return [{"substeps": 1}, {"substeps": 4}]
    return [{"substeps": 1}, {"substeps": 2}, {"substeps": 4}, {"substeps": 1, "tolerance": 1e-6},
            {"substeps": 1, "method": "projected_newton"}]


def blender_settings(scene, n, quick):
    """(quality, membrane stiffness multiplier) pairs; a scene may choose its own."""
    if hasattr(scene, "blender_settings"):
        return scene.blender_settings(n, quick)
    if quick:
        return [(5, 1.0), (20, 1.0)]
    return [(2, 1.0), (5, 1.0), (10, 1.0), (20, 1.0), (40, 1.0), (10, 0.1), (10, 10.0)]


def chart(title, unit, pts, path):
    """Error against wall time, log–log, one colour per solver, as a small standalone SVG (no
    plotting library needed): each point is one run, labelled with its resolution."""
    pts = [p for p in pts if p[3] is not None and p[4] > 0]
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
           f'<text x="{W / 2}" y="20" text-anchor="middle" font-size="13">{title}</text>']
    for e in range(x0, x1 + 1):
        out.append(f'<line x1="{sx(e)}" y1="{M}" x2="{sx(e)}" y2="{H - M}" stroke="#ddd"/>')
        out.append(f'<text x="{sx(e)}" y="{H - M + 15}" text-anchor="middle">1e{e} s</text>')
    for e in range(y0, y1 + 1):
        out.append(f'<line x1="{M}" y1="{sy(e)}" x2="{W - M}" y2="{sy(e)}" stroke="#ddd"/>')
        out.append(f'<text x="{M - 5}" y="{sy(e) + 4}" text-anchor="end">1e{e} {unit}</text>')
    for solver, n, setting, err, secs in pts:
        x, y = sx(math.log10(secs)), sy(math.log10(max(err, 1e-12)))
        c = colour.get(solver, "gray")
        out.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{c}"><title>{solver} {n}, {setting}: '
                   f'{err:.2e} {unit} in {secs:.2f} s</title></circle>')
        out.append(f'<text x="{x + 6:.1f}" y="{y - 4:.1f}" fill="{c}" font-size="9">{n}</text>')
    for k, (name, c) in enumerate(colour.items()):
        out.append(f'<circle cx="{W - M - 80}" cy="{M + 10 + 16 * k}" r="4" fill="{c}"/>'
                   f'<text x="{W - M - 70}" y="{M + 14 + 16 * k}">{name}</text>')
    out.append("</svg>")
    pathlib.Path(path).write_text("\n".join(out))


def against_blender(pts):
    """For each run on Blender's front (no Blender run both faster and more accurate), the
    fastest Weft run at least as accurate: (Blender error, Blender s, Weft error, Weft s), Weft's
    None where none is."""
    ok = [p for p in pts if p[3] is not None]
    blender = sorted((p for p in ok if p[0] == "blender"), key=lambda p: (p[4], p[3]))
    front, best = [], math.inf
    for p in blender:
        if p[3] < best:
            front.append(p)
            best = p[3]
    out = []
    for b in front:
        weft = [p for p in ok if p[0] == "weft" and p[3] <= b[3]]
        w = min(weft, key=lambda p: p[4]) if weft else None
        out.append((b, w))
    return out


def repeated(run, times):
    """`run()` → (value, seconds, error, wall) `times` times: the first run's value and error
    (both solvers are deterministic), the median seconds and wall time (single runs of a few
    milliseconds vary by tens of percent on a busy machine)."""
    runs = [run() for _ in range(times)]
    if runs[0][0] is None:
        return runs[0]
    return runs[0][0], statistics.median(r[1] for r in runs), runs[0][2], statistics.median(r[3] for r in runs)


def run_scene(scene, runner, quick):
    ref = scene.reference(runner)
    rows = []
    times = runner.args.repeat
    for n in scene.sizes(quick):
        for setting in weft_settings(scene, quick):
            value, s, err, wall = repeated(lambda: runner.weft(scene, n, setting), times)
            label = ", ".join(f"{k} {v}" for k, v in setting.items())
            rows.append(("weft", n, label, value, s, err, wall))
        if runner.blender:
            for quality, stiffness in blender_settings(scene, n, quick):
                value, s, err, wall = repeated(lambda: runner.blender_run(scene, n, quality, stiffness), times)
                rows.append(("blender", n, f"quality {quality}, membrane ×{stiffness:g}", value, s, err, wall))
    pts = [(r[0], r[1], r[2], scene.error(r[3], ref) if r[3] is not None else None, r[4]) for r in rows]
    with open(runner.out / f"{scene.name}.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["solver", "resolution", "setting", f"error_{scene.unit}", "seconds", "process_seconds", "failure"])
        for (solver, n, setting, e, s), row in zip(pts, rows):
            w.writerow([solver, n, setting, "" if e is None else f"{e:.6e}", f"{s:.6f}", f"{row[6]:.3f}", row[5]])
    chart(scene.title, scene.unit, pts, runner.out / f"{scene.name}.svg")
    print(f"\n{scene.name}: chart {runner.out / (scene.name + '.svg')}")
    print("| solver | resolution | setting | error | simulation [s] | process [s] |")
    print("|---|---:|---|---:|---:|---:|")
    for (solver, n, setting, e, s), row in zip(pts, rows):
        shown = f"failed: {row[5]}" if e is None else f"{e:.2e} {scene.unit}"
        print(f"| {solver} | {n} | {setting} | {shown} | {s:.3g} | {row[6]:.2f} |")
    front = against_blender(pts)
    if front:
        print(f"\n{scene.name}: Blender's runs that no other Blender run beats in both error and time, "
              "and the fastest Weft run at least as accurate")
        print("| Blender | error | s | Weft | error | s | Blender s / Weft s |")
        print("|---|---:|---:|---|---:|---:|---:|")
        for b, w in front:
            tail = (f"{w[1]}, {w[2]} | {w[3]:.2e} | {w[4]:.3g} | {b[4] / w[4]:.1f}" if w else "none | | |")
            print(f"| {b[1]}, {b[2]} | {b[3]:.2e} | {b[4]:.3g} | {tail} |")
    return [f"{scene.name} {n}, {setting}: {row[5]}" for (solver, n, setting, e, s), row in zip(pts, rows)
            if solver == "weft" and e is None]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scenes", nargs="*", help=f"scenes to run: {', '.join(SCENES)} (default: all)")
    p.add_argument("--quick", action="store_true", help="two resolutions and two settings a solver")
    p.add_argument("--blender", default="blender")
    p.add_argument("--weft", default=str(HERE.parents[1] / "target/release/weft"))
    p.add_argument("--out", default="bench-out/peers")
    p.add_argument("--repeat", type=int, default=1, metavar="N",
                   help="run each setting N times and keep the median time (default 1)")
    a = p.parse_args()
    unknown = [s for s in a.scenes if s not in SCENES]
    if unknown:
        p.error(f"unknown scene {', '.join(unknown)}: the scenes are {', '.join(SCENES)}")
    out = pathlib.Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        runner = Runner(a, pathlib.Path(tmp), out)
        if runner.blender is None:
            print(f"Blender ({a.blender}) is not installed: its runs are skipped")
        failed = []
        for name in a.scenes or list(SCENES):
            failed += run_scene(SCENES[name], runner, a.quick)
    # Blender may fail (unstable settings are part of its sweep); a Weft run must not.
    if failed:
        raise SystemExit("Weft runs failed:\n" + "\n".join(failed))


if __name__ == "__main__":
    main()
