# Blender's own glTF exports of CesiumMan, as he comes (plain), with a body shape left on
# (shaped: a shape key at 0.7) and mirrored at his root (scale x -1), with Blender's rest
# position of each: the bind pose an artist models garments on; and the shaped one as FBX.
# Run by tests/blender.rs: blender -b --factory-startup --python this -- CHARACTER OUT_DIR
# Prints one line "RESULT {json}": per export its file and the box of the rest-position mesh in
# glTF's axes (Y up).
import json
import sys

import numpy

numpy.bool = bool  # Blender 3.4's glTF importer needs it with numpy >= 1.24
import bpy

character, out = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=character)
scene = bpy.context.scene
armature = next(o for o in scene.objects if o.type == "ARMATURE")
body = next(o for o in scene.objects if o.type == "MESH")


def rest_box():
    armature.data.pose_position = "REST"
    bpy.context.view_layer.update()
    evaluated = body.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    # Blender is Z up; its glTF export writes (x, z, -y).
    points = [evaluated.matrix_world @ v.co for v in mesh.vertices]
    points = [(p.x, p.z, -p.y) for p in points]
    evaluated.to_mesh_clear()
    armature.data.pose_position = "POSE"
    return [[min(p[k] for p in points) for k in range(3)], [max(p[k] for p in points) for k in range(3)]]


result = {}
for name in ("plain", "shaped", "mirrored"):
    if name == "shaped":
        # A body shape left on: a shape key pushing every vertex 2 cm out along its normal, at
        # 0.7 (glTF: a morph target with default weight 0.7).
        body.shape_key_add(name="Basis")
        heavy = body.shape_key_add(name="Heavy")
        for v, point in zip(body.data.vertices, heavy.data):
            point.co = v.co + v.normal * 0.02
        heavy.value = 0.7
    if name == "mirrored":
        heavy.value = 0.0
        for o in scene.objects:
            if o.parent is None:
                o.scale.x *= -1
        bpy.context.view_layer.update()
    path = f"{out}/{name}.glb"
    bpy.ops.export_scene.gltf(filepath=path, export_format="GLB")
    result[name] = {"file": path, "rest_box": rest_box()}
    if name == "shaped":
        result["shaped_fbx"] = f"{out}/shaped.fbx"
        bpy.ops.export_scene.fbx(filepath=result["shaped_fbx"])
print("RESULT " + json.dumps(result))
