"""The Blender add-on (blender/drape_bake), run headless by tests/blender.rs:

    blender -b --factory-startup --python tests/blender_addon.py -- DRAPE WORK

Installs the add-on from a zip made as docs/blender.md says, builds a character (a cylinder
skinned to a two-bone armature whose chest sways, an action over frames 1001-1024 at 24 fps)
and a cape modelled behind its back, bakes through the add-on, and prints `RESULT {json}`:
for frames 1001, 1012 and 1024, the largest distance between the baked object's evaluated
vertices (world, turned Y up) and drape's OBJ frame, and between the character Blender shows
and the character drape baked (nearest vertices both ways); then a bake cancelled after a few
frames and resumed, and a bad input's message.
"""
import json
import math
import os
import sys
import time
import zipfile

import bpy

drape, work = sys.argv[sys.argv.index("--") + 1:][:2]
root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "blender")
archive = os.path.join(work, "drape_bake.zip")
with zipfile.ZipFile(archive, "w") as z:
    for folder, _, files in os.walk(os.path.join(root, "drape_bake")):
        for f in files:
            if f.endswith(".py"):
                path = os.path.join(folder, f)
                z.write(path, os.path.relpath(path, root))
bpy.ops.preferences.addon_install(filepath=archive)
bpy.ops.preferences.addon_enable(module="drape_bake")
addon = sys.modules["drape_bake"]
bpy.context.preferences.addons["drape_bake"].preferences.executable = drape

scene = bpy.context.scene
for o in list(bpy.data.objects):
    bpy.data.objects.remove(o)
scene.render.fps = 24
scene.frame_start, scene.frame_end = 1001, 1024

bpy.ops.mesh.primitive_cylinder_add(radius=0.15, depth=1.6, location=(0, 0, 0.8), vertices=16)
body = bpy.context.object
body.name = "body"
bpy.ops.object.mode_set(mode="EDIT")
bpy.ops.mesh.subdivide(number_cuts=7)
bpy.ops.object.mode_set(mode="OBJECT")
bpy.ops.object.transform_apply(location=True)
rig = bpy.data.objects.new("rig", bpy.data.armatures.new("rig"))
scene.collection.objects.link(rig)
bpy.context.view_layer.objects.active = rig
bpy.ops.object.mode_set(mode="EDIT")
hips = rig.data.edit_bones.new("hips")
hips.head, hips.tail = (0, 0, 0), (0, 0, 0.8)
chest = rig.data.edit_bones.new("chest")
chest.head, chest.tail, chest.parent = (0, 0, 0.8), (0, 0, 1.6), hips
bpy.ops.object.mode_set(mode="OBJECT")
body.select_set(True)
rig.select_set(True)
bpy.context.view_layer.objects.active = rig
bpy.ops.object.parent_set(type="ARMATURE_AUTO")
rig.animation_data_create()
action = bpy.data.actions.new("sway")
rig.animation_data.action = action
bone = rig.pose.bones["chest"]
bone.rotation_mode = "XYZ"
for frame, angle in [(1001, 0), (1012, 25), (1024, -15)]:
    bone.rotation_euler = (math.radians(angle), 0, 0)
    bone.keyframe_insert("rotation_euler", frame=frame)

garments = bpy.data.collections.new("garments")
scene.collection.children.link(garments)
bpy.ops.mesh.primitive_grid_add(x_subdivisions=9, y_subdivisions=13, size=1)
cape = bpy.context.object
cape.name = "cape"
# Wrapped round the back, 4 cm off the skin, from the shoulders down: x is the arc.
for v in cape.data.vertices:
    arc, height = v.co.x * 0.4, v.co.y * 0.6
    v.co = (0.19 * math.sin(arc / 0.19), 0.19 * math.cos(arc / 0.19), 1.2 + height)
for c in cape.users_collection:
    c.objects.unlink(cape)
garments.objects.link(cape)

s = scene.drape
s.character, s.garments, s.clip = body, garments, action
s.preroll_settle, s.preroll_blend = 5, 5
s.preset, s.spacing, s.character_frames = "DRAFT", 0.03, True
s.output = os.path.join(work, "out")


def obj_vertices(path):
    with open(path) as f:
        return [tuple(map(float, l.split()[1:4])) for l in f if l.startswith("v ")]


def evaluated(obj):
    e = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    m = e.to_mesh()
    points = [addon.yup(obj.matrix_world @ v.co) for v in m.vertices]
    e.to_mesh_clear()
    return points


def nearest(a, b):
    return max(min(math.dist(p, q) for q in b) for p in a)


result = {"frames": {}}
started = time.time()
bpy.ops.drape.bake(wait=True)
result["bake_s"] = time.time() - started
baked = bpy.data.objects.get("cape_drape")
result["made"] = baked is not None
result["cape_hidden"] = cape.hide_get() and cape.hide_render
job = addon._jobs[scene.name]
for frame in (1001, 1012, 1024):
    scene.frame_set(frame)
    drape_cape = obj_vertices(os.path.join(job.bake, "obj", "cape_%04d.obj" % frame))
    shown = evaluated(baked)
    drape_body = obj_vertices(os.path.join(job.bake, "obj", "character_%04d.obj" % frame))
    body_now = evaluated(body)
    result["frames"][frame] = {
        "vertices": [len(shown), len(drape_cape)],
        "garment": max(math.dist(p, q) for p, q in zip(shown, drape_cape)),
        "character": max(nearest(body_now, drape_body), nearest(drape_body, body_now)),
        "cape_moves": max(math.dist(p, q) for p, q in zip(drape_cape, obj_vertices(os.path.join(job.bake, "obj", "cape_1001.obj")))),
    }
result["uv"] = len(baked.data.uv_layers) > 0

# Cancel after a few frames (SIGINT: drape checkpoints and stops), then Resume.
s.output = os.path.join(work, "cancelled")
job = addon.prepare(bpy.context)
job.start(drape)
while job.running() and job.done < 3:
    time.sleep(0.01)
job.cancel()
result["cancelled_code"] = job.wait()
result["cancelled_after"] = job.done
bpy.ops.drape.bake(resume=True, wait=True)
with open(os.path.join(job.bake, "report.json")) as f:
    report = json.load(f)
result["resumed"] = report.get("resumed") or {}
result["resumed_frames"] = report["frames_baked"]

result["warnings"] = addon._jobs[scene.name].warnings()

# A character animated without an armature (a keyframed object, baked as one OBJ per frame).
mover = body.copy()
mover.data = body.data.copy()
mover.name = "mover"
for m in list(mover.modifiers):
    mover.modifiers.remove(m)
mover.parent = None
scene.collection.objects.link(mover)
for frame, x in [(1000, 0.0), (1024, 0.3)]:
    mover.location = (x, 0, 0)
    mover.keyframe_insert("location", frame=frame)
hooded = bpy.data.collections.new("hooded")
scene.collection.children.link(hooded)
cape2 = cape.copy()
cape2.data = cape.data.copy()
cape2.name = "cape2"
hooded.objects.link(cape2)
s.character, s.garments, s.clip = mover, hooded, None
s.output = os.path.join(work, "sequence")
bpy.ops.drape.bake(wait=True)
job = addon._jobs[scene.name]
baked2 = bpy.data.objects.get("cape2_drape")
result["sequence"] = {}
for frame in (1001, 1012, 1024):
    scene.frame_set(frame)
    drape_cape = obj_vertices(os.path.join(job.bake, "obj", "cape2_%04d.obj" % frame))
    drape_body = obj_vertices(os.path.join(job.bake, "obj", "character_%04d.obj" % frame))
    body_now = evaluated(mover)
    result["sequence"][frame] = {
        "garment": max(math.dist(p, q) for p, q in zip(evaluated(baked2), drape_cape)),
        "character": max(nearest(body_now, drape_body), nearest(drape_body, body_now)),
    }
s.character, s.garments, s.clip = body, garments, action

# Bad input: drape's message reaches the user (a garment with no faces).
bad = bpy.data.collections.new("bad")
scene.collection.children.link(bad)
wire = bpy.data.meshes.new("wire")
wire.from_pydata([(0, 0.3, 1.0), (0.1, 0.3, 1.0)], [(0, 1)], [])
bad.objects.link(bpy.data.objects.new("wire", wire))
s.garments = bad
try:
    addon.bake(bpy.context)
    result["bad_input"] = None
except addon.DrapeError as e:
    result["bad_input"] = str(e)
print("RESULT " + json.dumps(result))
