#!/usr/bin/env python3
"""Newton counts of an example over an ensemble of rounding-level perturbations.

A contact scene's Newton iterations a step are chaotic in the last bits of its input: hair
falling into a pile takes 9.72 to 10.71 iterations a step over 24 frames when gravity is
changed by k * 1e-12 of itself (k = 0..7; BENCHMARKS.md, twenty-third session). One run
then cannot tell a solver change worth 5 % from rounding. This script runs the graph once
per k with the gravity Behavior's acceleration scaled by (1 + k * 1e-12), reads each run's
`--stats-json`, and prints every run and the mean, smallest and largest of:
Newton iterations a step, retried substeps, exact-check re-solves and wall seconds.

    python3 bench/ensemble.py graphs/hair_pile.json --runs 8
    python3 bench/ensemble.py graphs/hair_on_head.json --runs 8 --weft OLD/weft

Counts are deterministic (the same inputs give bit-identical runs); wall times are not, so
compare two binaries on a quiet machine. Exits non-zero if a run fails.

Cloth is not chaotic at this scale: cloth_drape takes the same 793-794 iterations for
every k even at --step 1e-6, so the default ensemble of a cloth example is one scene run
k times. For cloth, compare solvers over a family of nearby scenes instead, with gravity
spread over half a percent (BENCHMARKS.md, forty-first session):

    python3 bench/ensemble.py graphs/cloth_pile.json --runs 6 --step 1e-3
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

DEFAULT_GRAVITY = [0.0, -9.81, 0.0]


def gravity_node(graph, name):
    """The gravity Behavior's node id and acceleration: `name` if given, else the only node
    of type behavior.gravity."""
    nodes = graph.get("nodes", {})
    if name:
        if name not in nodes:
            sys.exit(f"ensemble: no node '{name}' in the graph")
        found = [name]
    else:
        found = [k for k, v in nodes.items() if v.get("type") == "behavior.gravity"]
        if len(found) != 1:
            sys.exit(f"ensemble: {len(found)} behavior.gravity nodes; name one with --gravity")
    node = found[0]
    acc = nodes[node].get("params", {}).get("acceleration", DEFAULT_GRAVITY)
    return node, [float(a) for a in acc]


def totals(stats):
    """Sums over every solver node's frames (solid_frames details)."""
    t = {"newton": 0, "steps": 0, "retries": 0, "resolves": 0}
    for node in stats.get("nodes", []):
        frames = (node.get("details") or {}).get("solid_frames") or []
        for f in frames:
            t["newton"] += f.get("newton_iterations", 0)
            t["steps"] += f.get("steps", 0)
            t["retries"] += f.get("retries", 0)
            t["resolves"] += (f.get("contacts") or {}).get("resolves", 0)
    return t


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("graph")
    ap.add_argument("--runs", type=int, default=8, help="perturbations k = 0..runs-1")
    ap.add_argument("--frames", default="0..24")
    ap.add_argument("--weft", default="target/release/weft", help="the weft binary")
    ap.add_argument("--gravity", default="", help="the gravity node (default: the only one)")
    ap.add_argument("--step", type=float, default=1e-12,
                    help="relative change per k (1e-3 for cloth: see the module's doc)")
    a = ap.parse_args()
    with open(a.graph) as f:
        node, acc = gravity_node(json.load(f), a.gravity)
    rows = []
    for k in range(a.runs):
        g = [c * (1.0 + k * a.step) for c in acc]
        with tempfile.TemporaryDirectory() as d:
            stats_file = os.path.join(d, "stats.json")
            cmd = [a.weft, "run", a.graph, "--frames", a.frames, "-q", "--no-checkpoints",
                   "--out", os.path.join(d, "out"), "--stats-json", stats_file,
                   "--set", f"{node}.acceleration={json.dumps(g)}"]
            t0 = time.monotonic()
            run = subprocess.run(cmd, capture_output=True, text=True)
            wall = time.monotonic() - t0
            if run.returncode != 0:
                sys.exit(f"ensemble: run k={k} failed:\n{run.stderr}")
            with open(stats_file) as f:
                t = totals(json.load(f))
        if t["steps"] == 0:
            sys.exit("ensemble: the graph has no solver with solid_frames statistics")
        t["per_step"] = t["newton"] / t["steps"]
        t["wall"] = wall
        rows.append(t)
        print(f"k={k}  Newton it. a step {t['per_step']:.2f}  ({t['newton']} in {t['steps']} steps)"
              f"  retried {t['retries']}  re-solves {t['resolves']}  wall {wall:.2f} s")
    print(f"{a.graph}, {a.runs} runs (gravity x (1 + k * {a.step:g})):")
    for key, label in [("per_step", "Newton it. a step"), ("retries", "retried substeps"),
                       ("resolves", "re-solves"), ("wall", "wall s")]:
        v = [r[key] for r in rows]
        print(f"  {label:18s} mean {sum(v) / len(v):.2f}  min {min(v):.2f}  max {max(v):.2f}")


if __name__ == "__main__":
    main()
