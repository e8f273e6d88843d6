"""Blender's cloth on one bench/peers scene (run by peers.py inside Blender, headless):

    blender -b --factory-startup --python blender_cloth.py -- CONFIG.json

CONFIG holds: "obj" (a triangle mesh in Weft's y-up metres, as peers.py writes it; converted
to Blender's z-up exactly and back), "pins" (vertex indices held by Blender's pin group),
"mass" (kg a vertex), "tension", "compression", "shear", "bending" (Blender's stiffnesses),
"air_damping", "spring_damping" (tension, compression and shear damping), "bending_damping",
"pin_stiffness", "quality" (steps a frame), "frames", "sample" (the frames whose vertex
positions are written; frame 0 is the mesh as given), "out", and optionally "gravity" (the
scene's, m/s² along −z, Blender's units: see peers.py) and "time_scale". Faces may be
triangles or quads. Writes to "out": the wall
time of the simulation (its frame changes only, not Blender's start-up nor the sampling)
and the sampled positions in Weft's coordinates.
"""

import json
import sys
import time

import bpy

cfg = json.load(open(sys.argv[sys.argv.index("--") + 1]))

verts, faces = [], []
for line in open(cfg["obj"]):
    part = line.split()
    if part and part[0] == "v":
        x, y, z = map(float, part[1:4])
        verts.append((x, -z, y))  # Weft (x, y, z) is Blender (x, −z, y)
    elif part and part[0] == "f":
        faces.append(tuple(int(p.split("/")[0]) - 1 for p in part[1:]))

bpy.ops.wm.read_factory_settings(use_empty=True)
mesh = bpy.data.meshes.new("sheet")
mesh.from_pydata(verts, [], faces)
sheet = bpy.data.objects.new("sheet", mesh)
bpy.context.scene.collection.objects.link(sheet)
pins = sheet.vertex_groups.new(name="pins")
pins.add(cfg["pins"], 1.0, "REPLACE")

cloth = sheet.modifiers.new("cloth", "CLOTH")
s = cloth.settings
s.quality = cfg["quality"]
s.mass = cfg["mass"]
s.tension_stiffness = cfg["tension"]
s.compression_stiffness = cfg["compression"]
s.shear_stiffness = cfg["shear"]
s.bending_stiffness = cfg["bending"]
s.air_damping = cfg["air_damping"]
s.tension_damping = s.compression_damping = s.shear_damping = cfg["spring_damping"]
s.bending_damping = cfg["bending_damping"]
s.pin_stiffness = cfg["pin_stiffness"]
s.vertex_group_mass = "pins"
s.time_scale = cfg.get("time_scale", 1.0)
cloth.collision_settings.use_collision = False
cloth.collision_settings.use_self_collision = False
scene = bpy.context.scene
if "gravity" in cfg:
    scene.gravity = (0.0, 0.0, -cfg["gravity"])
scene.render.fps, scene.render.fps_base = 24, 1.0
frames = cfg["frames"]
# Blender's frame 1 is the initial state: its frame f + 1 is Weft's frame f (time f / 24 s).
scene.frame_start, scene.frame_end = 1, frames + 1
cloth.point_cache.frame_start, cloth.point_cache.frame_end = 1, frames + 1


def positions():
    ev = sheet.evaluated_get(bpy.context.evaluated_depsgraph_get())
    return [[p.x, p.z, -p.y] for p in (sheet.matrix_world @ v.co for v in ev.data.vertices)]


sample = set(cfg["sample"])
out = {}
seconds = 0.0
scene.frame_set(1)
if 0 in sample:
    out["0"] = positions()
for f in range(1, frames + 1):
    t0 = time.perf_counter()
    scene.frame_set(f + 1)
    seconds += time.perf_counter() - t0
    if f in sample:
        out[str(f)] = positions()
json.dump({"seconds": seconds, "vertices": len(verts), "positions": out}, open(cfg["out"], "w"))
