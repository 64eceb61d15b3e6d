"""One bake in Blender's cloth, for `drape bench peers`.

    blender -b --factory-startup --python blender_cloth.py -- JOB.json OUT QUALITY

`drape bench peers` writes JOB.json from a drape scene: the garment's particles and quad cells
(drape's own lattice, vertex order kept), its pins, mass, stiffness and damping, and the
character (the same file, clip and placement drape uses) with a ground plane. This script builds
that scene in Blender, steps every frame in order, and writes OUT/cloth_NNNN.obj and, with a
character, OUT/body_NNNN.obj (the character's evaluated meshes), both in drape's Y-up metres and
numbered as drape numbers its frames, plus OUT/timing.json: the milliseconds of each frame's
`frame_set` (the simulation and the character's evaluation; the export excluded) and of the same
frames with the cloth switched off (the character alone).

Blender's cloth counts time in frames whatever the frame rate (its point cache steps one unit per
frame), so SI values are converted with T = fps: a spring constant k [N/m] becomes
k * L / T^2 (Blender divides its stiffness by the mean rest edge length L), gravity is scaled by
1000 / T^2 (Blender multiplies `scene.gravity` by 0.001 per unit^2), and drape's velocity damping
rate g [1/s] becomes air_damping = 100 * g * m / T (Blender's drag is 0.01 * air_damping * v).
Spring dashpots are off, as drape has none. Shear springs are Blender's quad diagonals, which
resist tension only. drape's bend springs (two particles apart) resist no small bend, and
Blender's angular hinges have no such spring: the hinge stiffness is the one whose energy at a
right-angle fold equals the bend springs' (b = k_bend * 1.39 / T^2).
"""
import json
import math
import os
import sys
import time

import numpy

numpy.bool = bool  # Blender 3.4's glTF importer still uses numpy.bool
import bpy  # noqa: E402
from mathutils import Matrix  # noqa: E402

# drape's Y-up to Blender's Z-up: (x, y, z) -> (x, -z, y), a rotation (windings are kept).
Y_UP_TO_Z_UP = Matrix(((1, 0, 0, 0), (0, 0, -1, 0), (0, 1, 0, 0), (0, 0, 0, 1)))


def fail(message):
    print("blender_cloth.py: " + message, file=sys.stderr)
    sys.exit(1)


def to_blender(p):
    return (p[0], -p[2], p[1])


def write_obj(path, name, positions, faces=None):
    """positions: (n, 3) in Blender's frame; written in drape's (x, z, -y)."""
    lines = ["o " + name]
    lines += ["v %.7g %.7g %.7g" % (x, z, -y) for x, y, z in positions]
    for f in faces or ():
        lines.append("f " + " ".join(str(i + 1) for i in f))
    with open(path, "w") as out:
        out.write("\n".join(lines) + "\n")


def world_positions(ob, depsgraph):
    """The evaluated mesh of `ob` in world space, (n, 3), and its triangles."""
    ev = ob.evaluated_get(depsgraph)
    mesh = ev.to_mesh()
    n = len(mesh.vertices)
    flat = numpy.empty(n * 3, dtype=numpy.float32)
    mesh.vertices.foreach_get("co", flat)
    local = flat.reshape(n, 3).astype(numpy.float64)
    m = numpy.array(ev.matrix_world, dtype=numpy.float64)
    world = local @ m[:3, :3].T + m[:3, 3]
    mesh.calc_loop_triangles()
    triangles = [tuple(t.vertices) for t in mesh.loop_triangles]
    if numpy.linalg.det(m[:3, :3]) < 0:
        triangles = [(a, c, b) for a, b, c in triangles]
    ev.to_mesh_clear()
    return world, triangles


def play(owner, animation, seconds, fps, loop, frames):
    """Plays the NLA track named `animation` of `owner` (an object or shape-key block) from
    frame 1 (clip time 0), over `seconds` of clip, looped or held."""
    ad = owner.animation_data
    if ad is None:
        return False
    track = next((t for t in ad.nla_tracks if t.name == animation), None)
    if track is None or not track.strips:
        return False
    action = track.strips[0].action
    for t in list(ad.nla_tracks):
        ad.nla_tracks.remove(t)
    ad.action = None
    played = ad.nla_tracks.new()
    played.name = animation
    strip = played.strips.new(animation, 1, action)
    strip.action_frame_start = 0.0
    strip.action_frame_end = max(seconds * fps, 1e-3)
    strip.extrapolation = "HOLD"
    strip.repeat = math.ceil(frames / max(seconds * fps, 1e-3)) + 1 if loop else 1.0
    strip.blend_type = "REPLACE"
    return True


def import_character(job):
    """Imports the character's file, parents its roots to an empty carrying drape's placement,
    and plays its clip. Returns the mesh objects."""
    c = job["character"]
    before = set(bpy.data.objects)
    path = c["file"]
    if path.lower().endswith((".glb", ".gltf")):
        bpy.ops.import_scene.gltf(filepath=path)
    else:
        fail("%s: only glTF characters are compared (got %s)" % (path, os.path.splitext(path)[1]))
    new = [o for o in bpy.data.objects if o not in before]
    placement = bpy.data.objects.new("drape_placement", None)
    bpy.context.scene.collection.objects.link(placement)
    # drape places file coordinates (glTF, Y up) with M; Blender's importer gave C * p.
    m = Matrix([c["matrix"][i * 4:(i + 1) * 4] for i in range(4)])  # rows
    placement.matrix_world = Y_UP_TO_Z_UP @ m @ Y_UP_TO_Z_UP.inverted()
    for o in new:
        if o.parent is None:
            o.parent = placement
    played = 0
    if c.get("animation") is not None:
        for o in new:
            played += play(o, c["animation"], c["seconds"], job["fps"], c["loop"], job["frames"])
            keys = getattr(o.data, "shape_keys", None)
            if keys is not None:
                play(keys, c["animation"], c["seconds"], job["fps"], c["loop"], job["frames"])
        if played == 0:
            tracks = sorted({t.name for o in new if o.animation_data for t in o.animation_data.nla_tracks})
            fail("%s: no animation %r after import; Blender has %s" % (path, c["animation"], tracks))
    meshes = [o for o in new if o.type == "MESH"]
    for o in meshes:
        col = o.modifiers.new("Collision", "COLLISION")
        col.settings.thickness_outer = c["radius"]
        col.settings.thickness_inner = 0.0
        col.settings.cloth_friction = c["friction"]
    return meshes


def build_cloth(job, quality):
    g = job["cloth"]
    mesh = bpy.data.meshes.new("cloth")
    # Quads over the lattice's whole cells, and loose edges for the structural springs of
    # cells a hole cut in half: Blender springs every edge, as drape springs every lattice edge.
    mesh.from_pydata([to_blender(p) for p in g["vertices"]], g["edges"], g["quads"])
    mesh.update()
    cloth = bpy.data.objects.new("cloth", mesh)
    bpy.context.scene.collection.objects.link(cloth)
    if len(cloth.data.vertices) != len(g["vertices"]):
        fail("the cloth lost vertices on import")
    group = cloth.vertex_groups.new(name="pins")
    if g["pins"]:
        group.add(g["pins"], 1.0, "REPLACE")
    modifier = cloth.modifiers.new("Cloth", "CLOTH")
    s = modifier.settings
    t = float(job["fps"])
    s.quality = quality
    s.time_scale = 1.0
    s.mass = g["vertex_mass"]
    s.vertex_group_mass = "pins"
    s.effector_weights.gravity = 1000.0 / t ** 2
    length = g["mean_edge"]
    s.tension_stiffness = g["stretch"] * length / t ** 2
    s.compression_stiffness = g["stretch"] * length / t ** 2
    s.shear_stiffness = g["shear"] * length / t ** 2
    s.bending_model = "ANGULAR"
    s.bending_stiffness = g["bend"] * 1.39 / t ** 2
    s.tension_damping = s.compression_damping = s.shear_damping = s.bending_damping = 0.0
    s.air_damping = min(100.0 * job["damping"] * g["vertex_mass"] / t, 10.0)
    collide = modifier.collision_settings
    collide.use_collision = job["character"] is not None or job["plane"]
    collide.use_self_collision = False
    collide.distance_min = g["contact_radius"]
    cache = modifier.point_cache
    cache.frame_start = 1
    cache.frame_end = job["frames"] + 1
    return cloth, modifier


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 3:
        fail("usage: blender -b --python blender_cloth.py -- JOB.json OUT QUALITY")
    job = json.load(open(argv[0]))
    out, quality = argv[1], int(argv[2])
    os.makedirs(out, exist_ok=True)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o, do_unlink=True)
    scene = bpy.context.scene
    scene.render.fps = int(job["fps"])
    scene.render.fps_base = 1.0
    scene.gravity = to_blender(job["gravity"])
    # Frame 1 is the cloth's start (Blender simulates nothing there); frames 2 .. N + 1 are
    # the N frames drape bakes, each one frame's simulation after the one before.
    scene.frame_start, scene.frame_end = 1, job["frames"] + 1
    bodies = import_character(job) if job["character"] else []
    if job["plane"]:
        mesh = bpy.data.meshes.new("ground")
        r = 50.0
        mesh.from_pydata([(-r, -r, 0), (r, -r, 0), (r, r, 0), (-r, r, 0)], [], [(0, 1, 2, 3)])
        ground = bpy.data.objects.new("ground", mesh)
        scene.collection.objects.link(ground)
        ground.modifiers.new("Collision", "COLLISION").settings.thickness_outer = 0.001
    cloth, modifier = build_cloth(job, quality)
    frames = range(2, job["frames"] + 2)

    # The character alone: the same frames with the cloth off.
    modifier.show_viewport = False
    alone = []
    scene.frame_set(1)
    for f in frames:
        start = time.perf_counter()
        scene.frame_set(f)
        alone.append((time.perf_counter() - start) * 1e3)
    modifier.show_viewport = True
    scene.frame_set(1)

    times = []
    body_faces = None
    for f in frames:
        start = time.perf_counter()
        scene.frame_set(f)
        times.append((time.perf_counter() - start) * 1e3)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        number = job["frame_start"] + f - 2
        positions, _ = world_positions(cloth, depsgraph)
        if len(positions) != len(job["cloth"]["vertices"]):
            fail("frame %d: the cloth has %d vertices, not %d" % (f, len(positions), len(job["cloth"]["vertices"])))
        write_obj(os.path.join(out, "cloth_%04d.obj" % number), "cloth", positions)
        if bodies:
            parts, faces, base = [], [], 0
            for b in bodies:
                p, t = world_positions(b, depsgraph)
                parts.append(p)
                faces += [(a + base, b_ + base, c + base) for a, b_, c in t]
                base += len(p)
            body_faces = body_faces or faces
            write_obj(os.path.join(out, "body_%04d.obj" % number), "body", numpy.concatenate(parts), body_faces)
    json.dump(
        {
            "blender": bpy.app.version_string,
            "quality": quality,
            "frame_ms": times,
            "character_alone_ms": alone,
            "threads": bpy.context.scene.render.threads,
        },
        open(os.path.join(out, "timing.json"), "w"),
    )


try:
    main()
except SystemExit:
    raise
except Exception as e:  # a failed bake must not leave Blender waiting
    import traceback

    traceback.print_exc()
    fail(repr(e))
