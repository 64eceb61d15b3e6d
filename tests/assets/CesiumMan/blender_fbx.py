"""Writes CesiumMan as FBX with Blender 3.4 (how tests/assets/CesiumMan/CesiumMan.fbx was made).

blender -b --python blender_fbx.py -- CesiumMan-notexture.glb CesiumMan.fbx
The glTF importer needs numpy.bool, gone from new numpy. The clip's own frame range is baked
(Blender's default scene range, 250 frames at 24 fps, would make a 10 s clip).
"""
import numpy; numpy.bool = bool
import bpy, sys
argv = sys.argv[sys.argv.index("--") + 1:]
src, fbx = argv
bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=src)
scene = bpy.context.scene
acts = list(bpy.data.actions)
print("actions", [(a.name, tuple(a.frame_range)) for a in acts], "fps", scene.render.fps)
arm = [o for o in scene.objects if o.type == 'ARMATURE'][0]
act = acts[0]
arm.animation_data.action = act
scene.frame_start, scene.frame_end = int(act.frame_range[0]), int(act.frame_range[1])
bpy.ops.export_scene.fbx(filepath=fbx, bake_anim=True, bake_anim_use_all_actions=False, bake_anim_use_nla_strips=False, add_leaf_bones=False, path_mode='STRIP', bake_anim_simplify_factor=0.0)
