#!/usr/bin/env python3
"""`weft bench solid`'s hanging cloth as a graph file, to run with `weft run`.

The benchmark prints a few aggregate rows per size; as a graph the same sheet gives every
frame's statistics (`--stats-json`: Newton iterations, factorizations, inertia tries, rate
stops, seconds by phase), the OBJ of every frame, and takes `--set` overrides. The sheet: a
1 m square `geo.grid` of n × n vertices in the xz plane at y = 1 m, the shell material's and
density's defaults (no SEC nodes), held at two adjacent corners, gravity, no damping; one
implicit step a frame, Newton to 1e-4 m/s, at most 200 iterations (as the benchmark's
`one_step_a_frame`).

    python3 bench/sheet_graph.py 317 > /tmp/sheet317.json
    weft run /tmp/sheet317.json --frames 0..2 -q --no-checkpoints --out /tmp/sheet317 \\
        --stats-json /tmp/sheet317/stats.json

Counts match the benchmark's (317²: 7 Newton iterations a step over 2 frames; 128²: 8.83
over 6; BENCHMARKS.md, twenty-ninth session).
"""

import argparse
import json


def sheet(n):
    return {
        "format": "weft-graph",
        "version": 1,
        "meta": {
            "doc": f"weft bench solid's hanging cloth at {n}x{n} vertices (bench/sheet_graph.py)."
        },
        "nodes": {
            "grid": {
                "type": "geo.grid",
                "params": {"width": 1.0, "height": 1.0, "nx": n, "ny": n, "plane": "xz",
                           "center": [0.0, 1.0, 0.0]},
            },
            "cloth": {"type": "convert.cloth", "inputs": {"mesh": "grid.mesh"},
                      "params": {"name": "cloth"}},
            "pins": {"type": "convert.attachment", "inputs": {"target": "cloth.element"},
                     "params": {"name": "pins", "vertices": [0, n - 1]}},
            "material": {"type": "behavior.discrete_shell"},
            "gravity": {"type": "behavior.gravity"},
            "attach": {"type": "behavior.attachment"},
            "tree": {"type": "behavior.tree", "inputs": {
                "behaviors": ["material.behavior", "gravity.behavior", "attach.behavior"]}},
            "solve": {"type": "solver.solid",
                      "inputs": {"elements": ["cloth.element", "pins.element"],
                                 "tree": "tree.tree"},
                      "params": {"substeps": 1, "tolerance": 1.0e-4, "max_iterations": 200}},
            "corner": {"type": "scene.vertex", "inputs": {"scene": "solve.scene"},
                       "params": {"element": "cloth", "index": n * n - 1}},
            "obj": {"type": "output.obj", "inputs": {"scene": "solve.scene"},
                    "params": {"directory": "obj"}},
        },
        "outputs": {"corner": "corner.position", "obj": "obj.path"},
    }


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("n", type=int, help="vertices along each side (the benchmark: 32 … 317)")
    n = p.parse_args().n
    if n < 2:
        p.error("n must be at least 2")
    print(json.dumps(sheet(n), indent=1))


if __name__ == "__main__":
    main()
