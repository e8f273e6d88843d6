"""Weft for Blender: bake hair and cloth from a Weft graph file, with Blender objects as the
graph's inputs, and play the result back as a mesh cache.

Properties > Physics > Weft: pick a graph file and Load it; map Blender objects to the
graph's geometry (every mesh or curves source node of the graph: a mesh object becomes the
cloth's mesh or a collider, with its animation; a Curves object a groom's strands); map the
simulated elements to the mesh objects that show them; set parameters; Bake. The bake feeds
each mapped object's evaluated geometry (world space) frame by frame, pulls the solver's scene
frame by frame (Esc stops it), and writes one PC2 point cache per result object, read by a Mesh
Cache modifier, so the result plays in the viewport and renders.

Axes: Weft's graphs are y-up (gravity along −y), Blender's z-up; Blender (x, y, z) is Weft
(x, z, −y) and back, exactly (a permutation and a sign).

Errors from Weft (a graph file with problems, a refused value, a solver that fails) are
reported in Blender's interface and in the panel; they never raise out of an operator.
"""

bl_info = {
    "name": "Weft",
    "author": "Weft developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Physics > Weft",
    "description": "Bake hair and cloth (and their contacts) from a Weft graph file",
    "category": "Physics",
}

import os
import struct
import sys

import bpy
import numpy as np
from bpy.props import (BoolProperty, CollectionProperty, FloatProperty, IntProperty,
                       PointerProperty, StringProperty)

_VENDOR = os.path.join(os.path.dirname(__file__), "vendor")
if os.path.isdir(_VENDOR) and _VENDOR not in sys.path:
    sys.path.insert(0, _VENDOR)


def _weft():
    """The bundled `weft` module (imported on first use, so the add-on still registers and
    reports the problem if it cannot be loaded)."""
    import weft

    return weft


# Blender z-up → Weft y-up, and back.
def to_weft(p):
    return np.stack([p[:, 0], p[:, 2], -p[:, 1]], axis=1)


def to_blender(p):
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)


class WeftInput(bpy.types.PropertyGroup):
    node: StringProperty(name="Node")
    port: StringProperty(name="Port")
    kind: StringProperty(name="Kind")
    object: PointerProperty(name="Object", type=bpy.types.Object,
                            description="The Blender object whose geometry replaces this node's output")
    animated: BoolProperty(name="Animated", default=True,
                           description="Feed the object's shape at every frame (off: its shape at the start frame for all frames)")


class WeftResult(bpy.types.PropertyGroup):
    element: StringProperty(name="Element")
    kind: StringProperty(name="Kind")
    object: PointerProperty(name="Object", type=bpy.types.Object,
                            description="The mesh object that shows this element (same vertex count and order); none: the bake makes one")


class WeftParam(bpy.types.PropertyGroup):
    node: StringProperty()
    param: StringProperty()
    kind: StringProperty()
    float_value: FloatProperty(name="Value", precision=6)
    int_value: IntProperty(name="Value")
    bool_value: BoolProperty(name="Value")
    loaded: StringProperty(description="The value in the graph file, as JSON")


class WeftSettings(bpy.types.PropertyGroup):
    graph_path: StringProperty(name="Graph", subtype="FILE_PATH",
                               description="A Weft graph file (.json)")
    scene_node: StringProperty(name="Solver", description="The node whose scene output is baked")
    scene_port: StringProperty(default="scene")
    frame_start: IntProperty(name="Start", default=1)
    frame_end: IntProperty(name="End", default=48)
    cache_dir: StringProperty(name="Cache", subtype="DIR_PATH", default="//weft_cache",
                              description="Where the PC2 point caches are written")
    inputs: CollectionProperty(type=WeftInput)
    results: CollectionProperty(type=WeftResult)
    params: CollectionProperty(type=WeftParam)
    show_params: BoolProperty(name="Parameters", default=False)
    last_error: StringProperty()
    loaded_path: StringProperty(description="The graph file the lists were made from")
    status: StringProperty()


def _settings(context):
    return context.scene.weft


def _panel_value(w):
    return {"float": w.float_value, "int": w.int_value, "bool": w.bool_value}[w.kind]


def _changed(kind, value, loaded):
    """Whether a panel value differs from the file's. Blender keeps float properties in
    float32, so a float counts as changed only when its float32 differs from the file
    value's: an untouched 0.1 stays the file's 0.1, not float32(0.1)."""
    if kind == "float":
        return np.float32(value) != np.float32(loaded)
    return value != loaded


def load_graph(context):
    """Loads the graph file and fills the inputs, results and parameters from it. Raises
    weft.WeftError (LoadError lists every problem); then nothing in the panel changed."""
    import ast

    weft = _weft()
    s = _settings(context)
    path = bpy.path.abspath(s.graph_path)
    g = weft.Graph.load(path)
    # Read everything first; the panel changes only once the graph is known to be usable.
    solver, inputs, params, results = None, [], [], []
    for node in g.nodes:
        d = g.describe(node)
        if d["type"].startswith("solver.") and any(ty == "scene" for _, ty in d["outputs"]):
            solver = solver or node
        for port, ty in d["outputs"]:
            # Geometry sources (no inputs): what a host provides.
            if ty in ("mesh", "curves") and not d["inputs"]:
                inputs.append((node, port, ty))
        for p in d["params"]:
            kind = p["kind"] if isinstance(p["kind"], str) else next(iter(p["kind"]))
            # start_frame is the bake's first frame, set at each bake.
            if kind in ("float", "int", "bool") and p["name"] != "start_frame":
                params.append((node, p["name"], kind, p["value"]))
        # The simulated elements, from the nodes that make them (nothing is evaluated: the
        # inputs may not be mapped yet).
        if d["type"] in ("convert.cloth", "convert.hair"):
            name = next(p["value"] for p in d["params"] if p["name"] == "name")
            results.append((name, d["type"].split(".")[1]))
    if solver is None:
        raise weft.GraphError("the graph has no solver node with a scene output to bake")
    old_inputs = {(i.node, i.port): (i.object, i.animated) for i in s.inputs}
    old_results = {r.element: r.object for r in s.results}
    # Reloading the same file keeps the parameters the user changed in the panel (and takes
    # the file's value for the others, which may have been edited).
    old_params = {}
    if s.loaded_path == path:
        for w in s.params:
            value = _panel_value(w)
            if _changed(w.kind, value, ast.literal_eval(w.loaded)):
                old_params[(w.node, w.param)] = (w.kind, value)
    s.inputs.clear()
    s.results.clear()
    s.params.clear()
    for node, port, ty in inputs:
        i = s.inputs.add()
        i.node, i.port, i.kind = node, port, ty
        i.object, i.animated = old_inputs.get((node, port), (None, True))
    for node, name, kind, in_file in params:
        w = s.params.add()
        w.node, w.param, w.kind = node, name, kind
        kept_kind, value = old_params.get((node, name), (kind, in_file))
        if kept_kind != kind:
            value = in_file
        if kind == "float":
            w.float_value = float(value)
        elif kind == "int":
            w.int_value = int(value)
        else:
            w.bool_value = bool(value)
        w.loaded = repr(in_file)
    for name, kind in results:
        r = s.results.add()
        r.element, r.kind = name, kind
        r.object = old_results.get(name)
    s.scene_node, s.scene_port = solver, "scene"
    s.loaded_path = path
    s.last_error = ""
    s.status = f"loaded: {len(s.inputs)} inputs, {len(s.results)} simulated elements"
    return g


def _mesh_world(obj, depsgraph):
    """The evaluated mesh of `obj` in world space: (positions (N, 3) f64, triangles (M, 3))."""
    ev = obj.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    try:
        mesh.calc_loop_triangles()
        n = len(mesh.vertices)
        co = np.empty(3 * n, dtype=np.float32)
        mesh.vertices.foreach_get("co", co)
        tris = np.empty(3 * len(mesh.loop_triangles), dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", tris)
        m = np.array(ev.matrix_world, dtype=np.float64)
        local = co.astype(np.float64).reshape(-1, 3)
        world = local @ m[:3, :3].T + m[:3, 3]
        return world, tris.astype(np.uint32).reshape(-1, 3)
    finally:
        ev.to_mesh_clear()


def _curves_world(obj, depsgraph):
    """The evaluated Curves object `obj` in world space: (positions, offsets)."""
    ev = obj.evaluated_get(depsgraph)
    data = ev.data
    n = len(data.points)
    co = np.empty(3 * n, dtype=np.float32)
    data.position_data.foreach_get("vector", co)
    offsets = np.empty(len(data.curves) + 1, dtype=np.int32)
    data.curve_offset_data.foreach_get("value", offsets)
    m = np.array(ev.matrix_world, dtype=np.float64)
    world = co.astype(np.float64).reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
    return world, offsets.astype(np.uint32)


def _geometry(i, depsgraph):
    if i.kind == "mesh":
        if i.object.type != "MESH":
            raise ValueError(f"{i.node}.{i.port} takes a mesh object; '{i.object.name}' is {i.object.type}")
        p, t = _mesh_world(i.object, depsgraph)
    else:
        if i.object.type != "CURVES":
            raise ValueError(f"{i.node}.{i.port} takes a Curves (hair) object; '{i.object.name}' is {i.object.type}")
        p, t = _curves_world(i.object, depsgraph)
    return to_weft(p), t


def _apply_params(g, s):
    """Sets the parameters whose panel value differs from the file's."""
    import ast

    for w in s.params:
        value = _panel_value(w)
        if _changed(w.kind, value, ast.literal_eval(w.loaded)):
            g.set(w.node, w.param, float(value) if w.kind == "float" else value)


class Bake:
    """A bake in progress: the graph with the host's data fed, pulled one frame at a time
    (so the interface can show progress and stop it). Everything it needs from the panel
    is read when it starts: changing the panel during a bake changes the next bake."""

    def __init__(self, context):
        s = _settings(context)
        if s.frame_end < s.frame_start:
            raise ValueError(f"the frame range {s.frame_start}..{s.frame_end} is empty")
        self.scene = scene = context.scene
        self.graph = load_graph(context)
        _apply_params(self.graph, s)
        # The first baked frame is the objects' shape at the range's start.
        self.graph.set(s.scene_node, "start_frame", s.frame_start)
        self.source = (s.scene_node, s.scene_port)
        self.cache_dir = bpy.path.abspath(s.cache_dir)
        self.fps = scene.render.fps / scene.render.fps_base
        mapped = [i for i in s.inputs if i.object is not None]
        # An input object may show an earlier bake through its Weft mesh cache: feed its own
        # shape, not that.
        muted = [(m, m.show_viewport) for i in mapped for m in i.object.modifiers
                 if m.name == "Weft" and m.type == "MESH_CACHE"]
        current = scene.frame_current
        try:
            for m, _ in muted:
                m.show_viewport = False
            for i in mapped:
                frames = range(s.frame_start, s.frame_end + 1) if i.animated else [s.frame_start]
                for f in frames:
                    scene.frame_set(f)
                    geometry = _geometry(i, context.evaluated_depsgraph_get())
                    self.graph.feed(i.node, i.port, geometry, frame=f if i.animated else None)
        finally:
            for m, shown in muted:
                m.show_viewport = shown
            scene.frame_set(current)
        self.frames = list(range(s.frame_start, s.frame_end + 1))
        self.next = 0
        # (element, kind, object picked or None), as the panel had them at the start
        self.targets = [(r.element, r.kind, r.object) for r in s.results]
        # element → list of (N, 3) f64 positions in Weft's axes, one per frame
        self.results = {element: [] for element, _, _ in self.targets}
        # element → its triangles (cloth) or curve offsets (hair), from the first frame
        self.topology = {}

    def step(self):
        """Pulls the next frame; whether frames remain."""
        f = self.frames[self.next]
        scene = self.graph.pull_port(*self.source, f, self.fps)
        for name, frames in self.results.items():
            frames.append(scene[name]["positions"])
            if name not in self.topology:
                e = scene[name]
                self.topology[name] = e.get("triangles", e.get("offsets"))
        self.next += 1
        self.scene.weft.status = f"baked frame {f} ({self.next}/{len(self.frames)})"
        return self.next < len(self.frames)

    def write(self):
        """Writes a PC2 cache per result object (made when none was picked) and points a Mesh
        Cache modifier at it; the files written."""
        os.makedirs(self.cache_dir, exist_ok=True)
        written = []
        for element, kind, obj in self.targets:
            frames = self.results.get(element)
            if not frames:
                continue
            if obj is None:
                obj = self._new_object(element, kind, frames[0])
                for r in self.scene.weft.results:
                    if r.element == element and r.object is None:
                        r.object = obj
            if obj.type != "MESH" or len(obj.data.vertices) != len(frames[0]):
                raise ValueError(
                    f"'{obj.name}' cannot show '{element}': it needs a mesh with "
                    f"{len(frames[0])} vertices in the element's order")
            inverse = np.linalg.inv(np.array(obj.matrix_world, dtype=np.float64))
            local = [to_blender(p) @ inverse[:3, :3].T + inverse[:3, 3] for p in frames]
            path = os.path.join(self.cache_dir, f"{bpy.path.clean_name(obj.name)}.pc2")
            write_pc2(path, local, start=self.frames[0], rate=1.0)
            mod = obj.modifiers.get("Weft") or obj.modifiers.new("Weft", "MESH_CACHE")
            mod.cache_format = "PC2"
            mod.filepath = path
            mod.frame_start = self.frames[0]
            mod.interpolation = "NONE"
            written.append(path)
        self.scene.weft.status = f"baked {len(self.frames)} frames into {len(written)} cache(s)"
        return written

    def _new_object(self, element, kind, positions):
        """A mesh object to show an element no object was picked for: the cloth's triangles,
        or the strands as edges (for a Curves object cannot take a mesh cache)."""
        p = to_blender(positions)
        topology = self.topology.get(element)
        if kind == "cloth":
            faces, edges = [tuple(map(int, t)) for t in topology], []
        else:
            faces = []
            edges = [(int(k), int(k) + 1) for a, b in zip(topology[:-1], topology[1:])
                     for k in range(int(a), int(b) - 1)]
        mesh = bpy.data.meshes.new(f"{element} (Weft)")
        mesh.from_pydata([tuple(v) for v in p], edges, faces)
        obj = bpy.data.objects.new(f"{element} (Weft)", mesh)
        self.scene.collection.objects.link(obj)
        return obj


def write_pc2(path, frames, start, rate):
    """A PC2 point cache: header (POINTCACHE2, version 1, points, start frame, sample rate,
    samples), then float32 x, y, z per point per sample; written atomically."""
    points = len(frames[0])
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<12siiffi", b"POINTCACHE2\0", 1, points, float(start), float(rate), len(frames)))
        for p in frames:
            f.write(np.ascontiguousarray(p, dtype="<f4").tobytes())
    os.replace(tmp, path)


def bake(context):
    """Bakes the whole frame range at once (scripts and tests): the results (element → list
    of (N, 3) float64 positions in Weft's axes) and the cache files written."""
    b = Bake(context)
    wm = context.window_manager
    wm.progress_begin(0, len(b.frames))
    try:
        while b.step():
            wm.progress_update(b.next)
    finally:
        wm.progress_end()
    return b.results, b.write()


def _fatal(e):
    """Exceptions an operator must let through: the user's Ctrl-C and Blender's exit. Every
    other one, PyO3's PanicException (a BaseException) included, is reported."""
    return isinstance(e, (KeyboardInterrupt, SystemExit))


def _report_error(op, context, e):
    message = str(e).strip() or type(e).__name__
    _settings(context).last_error = message
    op.report({"ERROR"}, f"Weft: {message}")
    return {"CANCELLED"}


class WEFT_OT_load(bpy.types.Operator):
    """Load the graph file: list its inputs, simulated elements and parameters"""

    bl_idname = "weft.load"
    bl_label = "Load Graph"

    def execute(self, context):
        try:
            load_graph(context)
        except BaseException as e:  # every failure is reported, none escapes into Blender
            if _fatal(e):
                raise
            return _report_error(self, context, e)
        self.report({"INFO"}, _settings(context).status)
        return {"FINISHED"}


class WEFT_OT_bake(bpy.types.Operator):
    """Bake the frame range with Weft (Esc stops it) and play it back as a mesh cache"""

    bl_idname = "weft.bake"
    bl_label = "Bake"

    _timer = None
    _bake = None

    def execute(self, context):
        try:
            _, written = bake(context)
        except BaseException as e:
            if _fatal(e):
                raise
            return _report_error(self, context, e)
        self.report({"INFO"}, f"Weft: wrote {len(written)} cache(s)")
        return {"FINISHED"}

    def invoke(self, context, event):
        try:
            self._bake = Bake(context)
        except BaseException as e:
            if _fatal(e):
                raise
            return _report_error(self, context, e)
        wm = context.window_manager
        wm.progress_begin(0, len(self._bake.frames))
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _finish(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()

    def modal(self, context, event):
        if event.type == "ESC":
            self._finish(context)
            _settings(context).status = f"stopped after {self._bake.next} frames"
            self.report({"WARNING"}, "Weft: bake stopped")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            more = self._bake.step()
            context.window_manager.progress_update(self._bake.next)
            if more:
                return {"RUNNING_MODAL"}
            written = self._bake.write()
        except BaseException as e:
            self._finish(context)
            if _fatal(e):
                raise
            return _report_error(self, context, e)
        self._finish(context)
        self.report({"INFO"}, f"Weft: wrote {len(written)} cache(s)")
        return {"FINISHED"}


class WEFT_PT_panel(bpy.types.Panel):
    bl_label = "Weft"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "physics"

    def draw(self, context):
        s = _settings(context)
        col = self.layout.column()
        row = col.row(align=True)
        row.prop(s, "graph_path", text="")
        row.operator("weft.load", text="", icon="FILE_REFRESH")
        if s.inputs:
            col.label(text="Inputs (Blender objects)")
            for i in s.inputs:
                row = col.row(align=True)
                row.prop(i, "object", text=f"{i.node}.{i.port}")
                row.prop(i, "animated", text="", icon="ANIM")
        if s.results:
            col.label(text="Results (mesh objects)")
            for r in s.results:
                col.prop(r, "object", text=r.element)
        if s.params:
            col.prop(s, "show_params", icon="TRIA_DOWN" if s.show_params else "TRIA_RIGHT")
            if s.show_params:
                for w in s.params:
                    col.prop(w, f"{w.kind}_value", text=f"{w.node}.{w.param}")
        row = col.row(align=True)
        row.prop(s, "frame_start")
        row.prop(s, "frame_end")
        col.prop(s, "cache_dir")
        col.operator("weft.bake", icon="PHYSICS")
        if s.status:
            col.label(text=s.status)
        if s.last_error:
            box = col.box()
            for line in s.last_error.splitlines()[:8]:
                box.label(text=line, icon="ERROR")


_classes = (WeftInput, WeftResult, WeftParam, WeftSettings, WEFT_OT_load, WEFT_OT_bake, WEFT_PT_panel)


def register():
    for c in _classes:
        bpy.utils.register_class(c)
    bpy.types.Scene.weft = PointerProperty(type=WeftSettings)


def unregister():
    del bpy.types.Scene.weft
    for c in reversed(_classes):
        bpy.utils.unregister_class(c)
