"""Blender's cloth on the hanging ribbon (run by ribbon.py inside Blender, headless):

    blender -b --factory-startup --python blender_ribbon.py -- RIBBON.obj QUALITY STIFFNESS FRAMES OUT.json

Reads the ribbon (an OBJ in Weft's y-up metres, as ribbon.py writes it; converted to
Blender's z-up exactly), pins its two end columns, runs Blender's cloth for FRAMES frames at
24 fps with QUALITY steps a frame and tension/compression/shear stiffness STIFFNESS (bending
and damping fixed), and writes the mid-span sag at the last frame and the wall time of the
simulation (frame changes only, not Blender's start-up) to OUT.json.
"""

import json
import sys
import time

import bpy

obj_path, quality, stiffness, frames, out = sys.argv[sys.argv.index("--") + 1:]
quality, stiffness, frames = int(quality), float(stiffness), int(frames)

verts, faces = [], []
for line in open(obj_path):
    part = line.split()
    if part and part[0] == "v":
        x, y, z = map(float, part[1:4])
        verts.append((x, -z, y))  # Weft (x, y, z) is Blender (x, −z, y)
    elif part and part[0] == "f":
        faces.append(tuple(int(p.split("/")[0]) - 1 for p in part[1:4]))

bpy.ops.wm.read_factory_settings(use_empty=True)
mesh = bpy.data.meshes.new("ribbon")
mesh.from_pydata(verts, [], faces)
ribbon = bpy.data.objects.new("ribbon", mesh)
bpy.context.scene.collection.objects.link(ribbon)
xs = [v[0] for v in verts]
ends = [i for i, v in enumerate(verts) if v[0] in (min(xs), max(xs))]
pins = ribbon.vertex_groups.new(name="pins")
pins.add(ends, 1.0, "REPLACE")

cloth = ribbon.modifiers.new("cloth", "CLOTH")
s = cloth.settings
s.quality = quality
# Blender's default mass and air damping: the static shape of a near-inextensible ribbon
# does not depend on its weight, and with the chain's real 0.3 g a vertex the default air
# damping makes it creep like syrup (its sag still drifting after 16 s).
s.mass = 0.3
s.tension_stiffness = s.compression_stiffness = s.shear_stiffness = stiffness
s.bending_stiffness = 0.0
s.air_damping = 1.0
s.tension_damping = s.compression_damping = s.shear_damping = 5.0
s.pin_stiffness = 1000.0
s.vertex_group_mass = "pins"
cloth.collision_settings.use_collision = False
cloth.collision_settings.use_self_collision = False
scene = bpy.context.scene
scene.render.fps, scene.render.fps_base = 24, 1.0
scene.frame_start, scene.frame_end = 1, frames
cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, frames

scene.frame_set(1)
t0 = time.perf_counter()
for f in range(2, frames + 1):
    scene.frame_set(f)
seconds = time.perf_counter() - t0
ev = ribbon.evaluated_get(bpy.context.evaluated_depsgraph_get())
co = [ribbon.matrix_world @ v.co for v in ev.data.vertices]
mid_x = 0.5 * (min(xs) + max(xs))
near = sorted(co, key=lambda p: abs(p.x - mid_x))[:2]  # the middle column (2 rows)
sag = -sum(p.z for p in near) / len(near)
json.dump({"sag": sag, "seconds": seconds, "vertices": len(verts)}, open(out, "w"))
