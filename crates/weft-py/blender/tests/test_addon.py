"""The add-on tested in a real Blender, headless (.ci/run):

    blender -b --factory-startup --python-exit-code 1 --python test_addon.py -- \\
        ADDON.zip WEFT_BINARY WORKDIR

Installs and enables the add-on from its zip, builds a scene (a 10 × 10 grid over a UV
sphere), maps them to cloth_on_ball.json's two mesh inputs, bakes 24 frames, and checks:
- the baked positions equal `weft run` on the same graph and the same meshes (written to OBJ
  from what the add-on fed, read back exactly) bit for bit: both are the engine's f64 results;
- an animated collider is fed frame by frame (a rising ball lifts the cloth);
- a Curves object feeds a groom's strands, and the hair result gets a mesh object the bake
  makes, whose cache holds the roots where the Curves had them;
- the Mesh Cache the add-on wrote plays them back: the evaluated cloth at frame 12 equals the
  baked positions rounded to float32, exactly (Blender stores vertex positions in float32, so
  that is the closest it can hold; the rounding is the only difference);
- a graph file with errors gives an error message in Blender (the operator reports it and
  the panel keeps it) and no crash; so does baking with no graph.
Prints PASS and exits 0, or raises (Blender exits 1).
"""

import pathlib
import subprocess
import sys

import bpy
import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
GRAPH = HERE / "cloth_on_ball.json"
FRAMES = (1, 24)

zip_path, weft_bin, work = sys.argv[sys.argv.index("--") + 1:]
work = pathlib.Path(work)
work.mkdir(parents=True, exist_ok=True)

bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
bpy.ops.preferences.addon_enable(module="weft_blender")
import weft_blender  # noqa: E402  (installed just above)

# The scene: default objects removed; a grid (the cloth) 0.3 m above a sphere's top.
bpy.ops.object.select_all(action="SELECT")
bpy.ops.object.delete()
bpy.ops.mesh.primitive_grid_add(x_subdivisions=10, y_subdivisions=10, size=0.6, location=(0.0, 0.0, 0.5))
cloth = bpy.context.active_object
cloth.name = "Cloth"
bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=0.2, location=(0.0, 0.0, 0.0))
ball = bpy.context.active_object
ball.name = "Ball"
scene = bpy.context.scene
scene.frame_set(FRAMES[0])

s = scene.weft
s.graph_path = str(GRAPH)
s.frame_start, s.frame_end = FRAMES
s.cache_dir = str(work / "cache")
assert bpy.ops.weft.load() == {"FINISHED"}, s.last_error
inputs = {(i.node, i.port): i for i in s.inputs}
assert set(inputs) == {("clothmesh", "mesh"), ("ballmesh", "mesh")}, set(inputs)
for key, obj in ((("clothmesh", "mesh"), cloth), (("ballmesh", "mesh"), ball)):
    inputs[key].object = obj
    inputs[key].animated = False
results = {r.element: r for r in s.results}
assert set(results) == {"cloth"}, set(results)
results["cloth"].object = cloth
assert any(w.node == "damping" and w.param == "coefficient" for w in s.params)


# What the add-on feeds, written as OBJ for `weft run` (shortest round-trip reprs: exact).
def write_obj(path, obj):
    p, t = weft_blender._geometry(inputs[next(k for k, i in inputs.items() if i.object == obj)],
                                  bpy.context.evaluated_depsgraph_get())
    with open(path, "w") as f:
        for v in p:
            f.write("v %r %r %r\n" % (float(v[0]), float(v[1]), float(v[2])))
        for a, b, c in t:
            f.write("f %d %d %d\n" % (a + 1, b + 1, c + 1))


write_obj(work / "cloth.obj", cloth)
write_obj(work / "ball.obj", ball)

baked, written = weft_blender.bake(bpy.context)
assert len(written) == 1 and len(baked["cloth"]) == FRAMES[1] - FRAMES[0] + 1

run = subprocess.run(
    [weft_bin, "run", str(GRAPH), "--frames", f"{FRAMES[0]}..{FRAMES[1]}",
     "--set", f"clothmesh.path={work / 'cloth.obj'}", "--set", f"ballmesh.path={work / 'ball.obj'}",
     "--set", f"solve.start_frame={FRAMES[0]}",  # the add-on starts the solver at the bake's start
     "--out", str(work / "run"), "--no-checkpoints"],
    capture_output=True, text=True)
assert run.returncode == 0, run.stdout + run.stderr


def read_obj(path):
    return np.array([[float(x) for x in line.split()[1:4]]
                     for line in open(path) if line.startswith("v ")])


for k, f in enumerate(range(FRAMES[0], FRAMES[1] + 1)):
    want = read_obj(work / "run" / "obj" / f"cloth.{f:04d}.obj")
    got = baked["cloth"][k]
    assert want.shape == got.shape, (want.shape, got.shape)
    assert np.array_equal(want, got), f"frame {f}: largest difference {np.abs(want - got).max()}"
fell = baked["cloth"][0][:, 1].max() - baked["cloth"][-1][:, 1].max()
assert fell > 0.05, f"the cloth fell only {fell} m"

# The Mesh Cache plays the bake back: float32 of the baked positions, in the object's space.
mod = cloth.modifiers["Weft"]
assert mod.type == "MESH_CACHE" and mod.cache_format == "PC2"
for f in (1, 12, 24):
    scene.frame_set(f)
    ev = cloth.evaluated_get(bpy.context.evaluated_depsgraph_get())
    co = np.empty(3 * len(ev.data.vertices), dtype=np.float32)
    ev.data.vertices.foreach_get("co", co)
    inverse = np.linalg.inv(np.array(cloth.matrix_world, dtype=np.float64))
    local = weft_blender.to_blender(baked["cloth"][f - FRAMES[0]]) @ inverse[:3, :3].T + inverse[:3, 3]
    want = local.astype(np.float32).reshape(-1)
    assert np.array_equal(co, want), f"frame {f}: the cache plays back off by {np.abs(co - want).max()}"

# An animated collider: the ball rises 5 cm at a steady 5.2 cm/s; fed frame by frame, it
# lifts the resting cloth by as much. (Faster, 10 cm/s, the contacts stop converging: a
# deforming collider is taken at each frame's shape, so it steps into the cloth at a
# frame's first substep; see docs/contacts.md.)
ball.location = (0.0, 0.0, 0.0)
ball.keyframe_insert("location", frame=FRAMES[0])
ball.location = (0.0, 0.0, 0.05)
ball.keyframe_insert("location", frame=FRAMES[1])
for fc in ball.animation_data.action.fcurves:
    for k in fc.keyframe_points:
        k.interpolation = "LINEAR"
for i in s.inputs:
    i.animated = i.node == "ballmesh"
for w in s.params:  # a parameter set in the panel: the ADMM gets more rounds
    if (w.node, w.param) == ("solve", "contact_iterations"):
        w.int_value = 400
moving, _ = weft_blender.bake(bpy.context)
rise = moving["cloth"][-1][:, 1].max() - baked["cloth"][-1][:, 1].max()
assert abs(rise - 0.05) < 0.005, f"the ball rose 0.05 m and lifted the cloth {rise} m"

# Hair from a Blender Curves object (3 strands of 5 points, converted from a particle
# system) fed as the C example's strands; the hair result gets a mesh object made by the
# bake (its strands as edges), whose cache holds the roots where the Curves had them.
bpy.ops.mesh.primitive_plane_add(size=0.2, location=(0.0, 0.0, 0.6))
scalp = bpy.context.active_object
settings = scalp.modifiers.new("hair", "PARTICLE_SYSTEM").particle_system.settings
settings.type, settings.count, settings.hair_length, settings.hair_step = "HAIR", 3, 0.1, 4
assert bpy.ops.curves.convert_from_particle_system() == {"FINISHED"}
groom = next(o for o in bpy.data.objects if o.type == "CURVES")
s.graph_path = str(HERE.parents[2] / "weft-capi/tests/c/host_scene.json")
s.frame_start, s.frame_end = 1, 4
assert bpy.ops.weft.load() == {"FINISHED"}, s.last_error
for i in s.inputs:
    i.object, i.animated = (groom, False) if i.node == "tuft" else (None, False)
for r in s.results:
    r.object = None
hair, _ = weft_blender.bake(bpy.context)
made = next(r.object for r in s.results if r.element == "hair")
assert made is not None and len(made.data.vertices) == 15 and len(made.data.edges) == 12
roots, _ = weft_blender._curves_world(groom, bpy.context.evaluated_depsgraph_get())
for k in (0, 5, 10):  # each strand's root is held where the host put it
    assert np.array_equal(hair["hair"][-1][k], weft_blender.to_weft(roots)[k]), k
scene.frame_set(4)
ev = made.evaluated_get(bpy.context.evaluated_depsgraph_get())
co = np.empty(45, dtype=np.float32)
ev.data.vertices.foreach_get("co", co)
assert np.array_equal(co, weft_blender.to_blender(hair["hair"][-1]).astype(np.float32).reshape(-1))

# A graph file with errors: a message, the panel keeps it, Blender goes on.
bad = work / "bad.json"
bad.write_text('{"format": "weft-graph", "version": 1,\n'
               ' "nodes": {"a": {"type": "value.float", "params": {"value": "x"}}},\n'
               ' "outputs": {"y": "a.out"}}')
s.graph_path = str(bad)
try:
    bpy.ops.weft.load()
    raise AssertionError("loading a bad graph did not report an error")
except RuntimeError as e:  # how bpy.ops surfaces an operator's ERROR report
    assert "Weft" in str(e) and "line 2" in str(e), str(e)
assert "param 'value'" in s.last_error, s.last_error
s.graph_path = str(work / "missing.json")
try:
    bpy.ops.weft.bake()
    raise AssertionError("baking a missing graph did not report an error")
except RuntimeError as e:
    assert "missing.json" in str(e), str(e)
print("PASS: the add-on bakes what weft run computes, bit for bit; errors reach Blender's interface")
