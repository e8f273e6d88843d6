"""Weft: a node-graph simulation engine for hair, cloth and their coupling with water and air.

The Python face of the engine, for hosts (Blender, Maya, scripts, notebooks)::

    import weft
    g = weft.Graph.load("graphs/cloth_drape.json")
    g.set("damping", "coefficient", 0.2)
    g.feed("ballmesh", "mesh", (positions, triangles), frame=1)   # host data, per frame
    scene = g.pull_port("solve", "scene", frame=24)                 # dict of elements
    cloth = scene["cloth"]["positions"]                             # (N, 3) float64

Errors are exceptions derived from ``weft.WeftError``, carrying ``node``, ``field`` (the
parameter or port), ``line`` (graph files) and ``frame`` (evaluation), and ``problems``: every
problem found, as dicts with the same keys.
"""

import numpy as _np

from . import _weft
from ._weft import EvalError, GraphError, Interrupted, LoadError, WeftError

__version__ = _weft.__version__
__all__ = ["Graph", "WeftError", "LoadError", "GraphError", "EvalError", "Interrupted"]


def _flat(array, dtype, what):
    a = _np.ascontiguousarray(array, dtype=dtype)
    if a.ndim == 2 and a.shape[1] != 3 and what != "offsets":
        raise ValueError(f"{what} must be N × 3, not {a.shape}")
    return a.reshape(-1)


class Graph:
    """A loaded graph: list it, set its parameters, feed it host data, pull its outputs."""

    def __init__(self, native):
        self._g = native

    @classmethod
    def load(cls, path):
        """Loads the graph file at ``path``; raises ``LoadError`` listing every problem."""
        return cls(_weft.Graph.load(str(path)))

    @classmethod
    def from_string(cls, text, name="<memory>"):
        """Loads a graph from its JSON text; ``name`` names it in messages."""
        return cls(_weft.Graph.from_string(text, name))

    @property
    def nodes(self):
        """Node ids in evaluation order."""
        return self._g.nodes()

    @property
    def outputs(self):
        """The graph's outputs: a dict of name → type."""
        return dict(self._g.outputs())

    def describe(self, node):
        """A node's type, doc, inputs and outputs [(name, type)], and params (a list of
        dicts: name, kind, default, unit, doc, value)."""
        return self._g.describe(node)

    def params(self, node):
        """A node's parameters: name → current value."""
        return {p["name"]: p["value"] for p in self._g.describe(node)["params"]}

    def set(self, node, param, value):
        """Sets a parameter (validated as in a graph file); the node and its downstream are
        recomputed when next pulled. Raises ``GraphError`` naming the node and parameter."""
        self._g.set(node, param, value)

    def output_type(self, node, port):
        """The type of output ``port`` of ``node`` (``mesh``, ``curves``, ``float``, …)."""
        for name, ty in self._g.describe(node)["outputs"]:
            if name == port:
                return ty
        raise GraphError(f"node '{node}': no output '{port}'")

    def feed(self, node, port, value, frame=None):
        """Replaces output ``port`` of ``node`` with host data: for all frames (``frame``
        None) or as the sample of ``frame``, held until the next sample. ``value`` by the
        port's type: a mesh is ``(positions (N, 3), triangles (M, 3))``, curves are
        ``(positions (N, 3), offsets (K + 1,))``, a float a number. Feed every frame before
        pulling: a change upstream of a solver makes it start again."""
        ty = self.output_type(node, port)
        if ty == "mesh":
            positions, triangles = value
            self._g.feed_mesh(node, port, _flat(positions, _np.float64, "positions"),
                              _flat(triangles, _np.uint32, "triangles"), frame)
        elif ty == "curves":
            positions, offsets = value
            self._g.feed_curves(node, port, _flat(positions, _np.float64, "positions"),
                                _flat(offsets, _np.uint32, "offsets"), frame)
        elif ty == "float":
            self._g.feed_float(node, port, float(value), frame)
        else:
            raise GraphError(f"node '{node}': output '{port}' is {ty}; a host can feed "
                             "mesh, curves and float outputs")

    def unfeed(self, node, port):
        """Stops feeding an output (the node computes it again); whether it was fed."""
        return self._g.unfeed(node, port)

    @property
    def fed(self):
        """The fed outputs: a list of (node, port, frames or None for all frames)."""
        return self._g.fed()

    def set_output_root(self, directory=None):
        """Where file outputs (``output.*`` nodes) write; None for the working directory."""
        self._g.set_output_root(None if directory is None else str(directory))

    def pull(self, output, frame, fps=24.0):
        """Evaluates graph output ``output`` at ``frame``: a float, an array, a path, a
        ``(positions, triangles)`` mesh, ``(positions, offsets)`` curves, or a scene as a
        dict of element name → dict(kind, positions, triangles or offsets). The GIL is
        released while it runs; raises ``EvalError`` (node, frame) or ``Interrupted``."""
        return self._g.pull(output, frame, fps)

    def pull_port(self, node, port, frame, fps=24.0):
        """Evaluates output ``port`` of node ``node`` at ``frame`` (see ``pull``)."""
        return self._g.pull_port(node, port, frame, fps)

    def stats(self):
        """Per-node statistics (evaluations, steps, seconds, a solver's own report)."""
        import json

        return json.loads(self._g.stats_json())

    def interrupter(self):
        """A stop request for this graph's pulls, with ``set()`` and ``reset()``, that
        another thread may use while a pull runs (a Cancel button)."""
        return self._g.interrupter()
