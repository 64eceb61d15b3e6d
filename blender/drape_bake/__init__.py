"""drape for Blender: bake garments on an animated character with drape and play the result.

In the 3D view's sidebar (N), tab "drape": pick the character (a mesh with its armature, or a
mesh animated any other way, which is baked as a sequence of frames), the collection of
garment meshes modelled on it in its bind pose, the clip (an action), the frame range, the
pre-roll and an accuracy preset, and press "Bake with drape". The add-on writes the character
(glTF, or one OBJ per frame), the garments (OBJ) and a drape scene into the output folder,
runs the drape executable (Preferences > Add-ons > drape) with a progress bar and a Cancel
button (drape keeps a checkpoint; "Resume" continues from it), then adds each garment's bake
as a new object with a Mesh Cache modifier reading drape's PC2 cache, on Blender's timeline,
and hides the garment it came from. drape's own error messages are shown as they are.

Coordinates: drape works in metres, Y up; the add-on writes Blender's world coordinates turned
Y up (x, z, -y) and turns the results back (the baked objects are rotated 90 degrees about X).
"""

bl_info = {
    "name": "drape: garment baking",
    "author": "drape",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "View3D > Sidebar > drape",
    "description": "Bake garments on an animated character with drape and play the caches",
    "category": "Animation",
}

import json
import math
import os
import re
import shutil
import signal
import subprocess
import threading

import bpy

# Solver settings per preset: the substep's length and the iterations fixed, or accuracy
# targets with which drape chooses them frame by frame (docs/scene-format.md, `accuracy`). The
# substep is given in seconds (`timestep`), not per frame, so a preset is the same simulation
# at Blender's 24 fps as at 60: 20 substeps a frame at 24 fps are 2.5 times as long as at 60,
# and a poncho landing on a head stops the bake there (docs/benchmarks.md, "Frame rates").
PRESETS = {
    "DRAFT": {"timestep": 1 / 600, "solver": {"kind": "rbgs", "iterations": 5, "contact_passes": 2}},
    "STANDARD": {"timestep": 1 / 1200, "solver": {"kind": "rbgs", "iterations": 10, "contact_passes": 5}},
    "ACCURATE": {
        "solver": {"kind": "rbgs", "contact_passes": 5},
        "accuracy": {"max_strain": 0.05, "max_penetration": 0.005},
    },
}
CHARACTER = "character"
# The last job per scene name: the one Cancel stops and Resume continues.
_jobs = {}
PROGRESS = re.compile(r"^drape: (\d+) of (\d+) frames$")


def yup(v):
    """A Blender world point in drape's frame (metres, Y up)."""
    return (v[0], v[2], -v[1])


def safe_name(name):
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name) or "garment"


def preferences(context):
    addon = context.preferences.addons.get(__name__)
    return addon.preferences if addon else None


def drape_executable(context):
    prefs = preferences(context)
    path = prefs.executable if prefs and prefs.executable else ""
    return path or os.environ.get("DRAPE") or shutil.which("drape") or "drape"


class DrapeError(Exception):
    """A problem to show the user, as it is."""


def armature_of(obj):
    for m in obj.modifiers:
        if m.type == "ARMATURE" and m.object is not None:
            return m.object
    return obj.parent if obj.parent and obj.parent.type == "ARMATURE" else None


def garment_objects(settings):
    if settings.garments is None:
        raise DrapeError("pick the collection of garment meshes")
    found = [o for o in settings.garments.all_objects if o.type == "MESH" and o != settings.character]
    if not found:
        raise DrapeError(f"the collection {settings.garments.name!r} holds no mesh")
    return found


def write_obj(path, obj, depsgraph=None):
    """Writes `obj`'s mesh (evaluated when `depsgraph` is given) in world space, Y up,
    triangulated, with its active UV map."""
    source = obj.evaluated_get(depsgraph) if depsgraph else obj
    mesh = source.to_mesh()
    try:
        mesh.calc_loop_triangles()
        m = obj.matrix_world
        uv = mesh.uv_layers.active
        lines = ["# drape add-on: %s" % obj.name, "o %s" % safe_name(obj.name)]
        for v in mesh.vertices:
            lines.append("v %r %r %r" % yup(m @ v.co))
        if uv:
            for d in uv.data:
                lines.append("vt %r %r" % (d.uv[0], d.uv[1]))
        for t in mesh.loop_triangles:
            if uv:
                lines.append("f " + " ".join("%d/%d" % (v + 1, l + 1) for v, l in zip(t.vertices, t.loops)))
            else:
                lines.append("f " + " ".join(str(v + 1) for v in t.vertices))
        with open(path, "w") as f:
            f.write("\n".join(lines) + "\n")
    finally:
        source.to_mesh_clear()


class Job:
    """One bake: its folders, its command, and the drape process while it runs."""

    def __init__(self, folder, scene_file, garments, frame_start):
        self.folder = folder
        self.scene_file = scene_file
        self.frame_start = frame_start
        self.bake = os.path.join(folder, "bake")
        self.garments = garments  # (Blender object name, drape garment name)
        self.process = None
        self.done = 0
        self.frames = 0
        self.errors = []
        self.reader = None

    def command(self, executable, resume):
        c = [executable, "bake", self.scene_file, "--out", self.bake, "--progress-lines"]
        return c + (["--resume"] if resume else [])

    def start(self, executable, resume=False):
        try:
            self.process = subprocess.Popen(
                self.command(executable, resume),
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
            )
        except OSError as e:
            raise DrapeError(f"cannot run drape ({executable}): {e}; set its path in the add-on's preferences")
        self.errors = []
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        for line in self.process.stderr:
            line = line.rstrip("\n")
            m = PROGRESS.match(line)
            if m:
                self.done, self.frames = int(m.group(1)), int(m.group(2))
            elif line:
                self.errors.append(line)

    def running(self):
        return self.process is not None and self.process.poll() is None

    def cancel(self):
        """SIGINT: drape finishes its frame, writes a checkpoint and stops (exit 130)."""
        if self.running():
            self.process.send_signal(signal.SIGINT)

    def wait(self):
        code = self.process.wait()
        self.reader.join()
        return code

    def warnings(self):
        return [e for e in self.errors if e.startswith("drape: warning")]

    def message(self):
        errors = [e for e in self.errors if e.startswith("drape: error")]
        return (errors or self.errors or ["drape failed"])[-1]


def prepare(context):
    """Writes the character, the garments and the scene into the output folder; returns the
    job. Raises DrapeError for anything the user must fix."""
    settings = context.scene.drape
    scene = context.scene
    character = settings.character
    if character is None or character.type != "MESH":
        raise DrapeError("pick the character's mesh")
    garments = garment_objects(settings)
    start, end = (scene.frame_start, scene.frame_end) if settings.use_scene_range else (settings.frame_start, settings.frame_end)
    if end < start:
        raise DrapeError(f"the frame range {start}-{end} is empty")
    fps = scene.render.fps / scene.render.fps_base
    name = safe_name(os.path.splitext(os.path.basename(bpy.data.filepath))[0] or scene.name)
    root = bpy.path.abspath(settings.output) if bpy.data.filepath or not settings.output.startswith("//") else bpy.app.tempdir
    folder = os.path.join(root, name)
    inputs = os.path.join(folder, "inputs")
    os.makedirs(inputs, exist_ok=True)
    rig = armature_of(character)
    entry = {"name": CHARACTER, "radius": 0.01}
    if settings.preroll_settle + settings.preroll_blend > 0:
        entry["preroll"] = {"settle": settings.preroll_settle, "blend": settings.preroll_blend}
    if rig is not None:
        if settings.clip is None:
            raise DrapeError(f"pick the clip (an action) that animates {rig.name}")
        # From the frame before the first: drape starts its clock there (its frame k is at
        # time k + 1 frames after `time_offset`), and Blender writes key times as frame / fps.
        export_gltf(context, character, rig, settings.clip, os.path.join(inputs, "character.glb"), start - 1, end)
        entry.update({"file": "character.glb", "clip": "0", "time_offset": (start - 1) / fps})
    else:
        folder_frames = os.path.join(inputs, "character")
        os.makedirs(folder_frames, exist_ok=True)
        current = scene.frame_current
        # From the frame before the first, as for a clip: drape's frame k shows file k + 2.
        for k, f in enumerate(range(start - 1, end + 1)):
            scene.frame_set(f)
            write_obj(os.path.join(folder_frames, "frame_%04d.obj" % (k + 1)), character, context.evaluated_depsgraph_get())
        scene.frame_set(current)
        entry.update({"file": "character", "sequence_fps": fps})
    names = []
    entries = []
    for g in garments:
        n = safe_name(g.name)
        while n in names or n == CHARACTER:
            n += "_"
        names.append(n)
        write_obj(os.path.join(inputs, f"{n}.obj"), g)
        e = {"name": n, "kind": "mesh", "mesh": f"{n}.obj", "on": CHARACTER, "spacing": settings.spacing}
        attach = g.get("drape_attach", settings.attach)
        if attach in ("TOP_EDGE", "BOTTOM_EDGE"):
            e["attachments"] = [{"particles": attach.lower(), "character": CHARACTER}]
        entries.append(e)
    doc = {
        "name": name,
        "fps": fps,
        "frames": end - start + 1,
        "frame_start": start,
        "output": {"pc2": True, "gltf": "none", "character_obj": settings.character_frames},
        "garments": entries,
        "characters": [entry],
    }
    doc.update(json.loads(json.dumps(PRESETS[settings.preset])))
    if settings.floor:
        doc["colliders"] = [{"kind": "plane"}]
    scene_file = os.path.join(inputs, "scene.json")
    with open(scene_file, "w") as f:
        json.dump(doc, f, indent=2)
    job = Job(folder, scene_file, [(g.name, n) for g, n in zip(garments, names)], start)
    _jobs[context.scene.name] = job
    return job


def export_gltf(context, mesh, rig, action, path, start, end):
    """The character as glTF: its mesh skinned to its armature, `action` its one animation,
    sampled over the frames (Blender writes key times as frame / fps)."""
    scene = context.scene
    saved = (scene.frame_start, scene.frame_end, rig.animation_data.action if rig.animation_data else None)
    selected = [o for o in context.view_layer.objects if o.select_get()]
    try:
        if rig.animation_data is None:
            rig.animation_data_create()
        rig.animation_data.action = action
        scene.frame_start, scene.frame_end = start, end
        for o in context.view_layer.objects:
            o.select_set(o in (mesh, rig))
        bpy.ops.export_scene.gltf(
            filepath=path,
            export_format="GLB",
            use_selection=True,
            export_animations=True,
            export_nla_strips=False,
            export_frame_range=True,
            export_force_sampling=True,
            export_apply=False,
            export_yup=True,
            export_materials="NONE",
        )
    finally:
        scene.frame_start, scene.frame_end = saved[0], saved[1]
        rig.animation_data.action = saved[2]
        for o in context.view_layer.objects:
            o.select_set(o in selected)


def read_obj(path):
    vertices, uvs, faces = [], [], []
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                vertices.append(tuple(float(x) for x in w[1:4]))
            elif w[0] == "vt":
                uvs.append((float(w[1]), float(w[2])))
            elif w[0] == "f":
                faces.append([int(c.split("/")[0]) - 1 for c in w[1:]])
    return vertices, uvs, faces


def attach(context, job):
    """Adds each garment's bake as an object with a Mesh Cache modifier on drape's PC2 cache
    and hides the garment it came from. Returns the objects."""
    collection = bpy.data.collections.get("drape") or bpy.data.collections.new("drape")
    if collection.name not in context.scene.collection.children:
        context.scene.collection.children.link(collection)
    start = job.frame_start
    made = []
    for source_name, n in job.garments:
        rest = os.path.join(job.bake, "pc2", f"{n}_rest.obj")
        cache = os.path.join(job.bake, "pc2", f"{n}.pc2")
        vertices, _, faces = read_obj(rest)
        frame = os.path.join(job.bake, "obj", "%s_%04d.obj" % (n, start))
        uvs = read_obj(frame)[1] if os.path.exists(frame) else []
        mesh = bpy.data.meshes.new(f"{n}_drape")
        mesh.from_pydata(vertices, [], faces)
        if len(uvs) == len(vertices):
            layer = mesh.uv_layers.new(name="UVMap")
            for loop in mesh.loops:
                layer.data[loop.index].uv = uvs[loop.vertex_index]
        mesh.update()
        source = bpy.data.objects.get(source_name)
        if source is not None:
            for m in source.data.materials:
                mesh.materials.append(m)
        obj = bpy.data.objects.get(f"{n}_drape")
        if obj is None:
            obj = bpy.data.objects.new(f"{n}_drape", mesh)
            collection.objects.link(obj)
        else:
            old = obj.data
            obj.data = mesh
            if old.users == 0:
                bpy.data.meshes.remove(old)
            for m in list(obj.modifiers):
                obj.modifiers.remove(m)
        # drape's Y-up metres back to Blender's Z up.
        obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
        modifier = obj.modifiers.new("drape", "MESH_CACHE")
        modifier.cache_format = "PC2"
        modifier.filepath = cache
        # Blender reads a PC2 cache from its first sample at `frame_start`, whatever the header.
        modifier.frame_start = float(job.frame_start)
        obj["drape_source"] = source_name
        if source is not None:
            source.hide_set(True)
            source.hide_render = True
        made.append(obj)
    return made


def bake(context, resume=False):
    """Bakes to the end here (for scripts and headless runs); returns the objects made."""
    job = last_job(context) if resume else prepare(context)
    job.start(drape_executable(context), resume)
    code = job.wait()
    if code != 0:
        raise DrapeError(job.message())
    return attach(context, job)


def last_job(context):
    job = _jobs.get(context.scene.name)
    if job is None:
        raise DrapeError("nothing to resume: bake first")
    return job


class DRAPE_OT_bake(bpy.types.Operator):
    """Write the character, garments and scene, bake with drape, and attach the caches"""

    bl_idname = "drape.bake"
    bl_label = "Bake with drape"

    resume: bpy.props.BoolProperty(default=False, options={"SKIP_SAVE"})
    wait: bpy.props.BoolProperty(
        name="Wait", description="Bake to the end before returning (scripts, background mode)", default=False, options={"SKIP_SAVE"}
    )

    def execute(self, context):
        if self.wait or bpy.app.background:
            try:
                made = bake(context, self.resume)
            except DrapeError as e:
                self.report({"ERROR"}, str(e))
                return {"CANCELLED"}
            for w in last_job(context).warnings():
                self.report({"WARNING"}, w)
            self.report({"INFO"}, "drape: baked %d garment(s)" % len(made))
            return {"FINISHED"}
        return self.invoke(context, None)

    def invoke(self, context, event):
        settings = context.scene.drape
        try:
            job = last_job(context) if self.resume else prepare(context)
            job.start(drape_executable(context), self.resume)
        except DrapeError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        settings.progress, settings.status = 0.0, "baking…"
        self.job = job
        self.timer = context.window_manager.event_timer_add(0.25, window=context.window)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        settings = context.scene.drape
        job = self.job
        if job.frames:
            settings.progress = 100.0 * job.done / job.frames
            settings.status = "frame %d of %d" % (job.done, job.frames)
        for area in context.screen.areas:
            area.tag_redraw()
        if job.running():
            return {"PASS_THROUGH"}
        context.window_manager.event_timer_remove(self.timer)
        code = job.wait()
        if code == 0:
            made = attach(context, job)
            for w in job.warnings():
                self.report({"WARNING"}, w)
            settings.status = "baked %d garment(s)" % len(made)
            return {"FINISHED"}
        if code == 130:
            settings.status = "cancelled after frame %d: Resume continues from the checkpoint" % job.done
            return {"CANCELLED"}
        settings.status = job.message()
        self.report({"ERROR"}, job.message())
        return {"CANCELLED"}


class DRAPE_OT_cancel(bpy.types.Operator):
    """Stop the bake: drape finishes its frame and keeps a checkpoint that Resume continues"""

    bl_idname = "drape.cancel"
    bl_label = "Cancel"

    def execute(self, context):
        job = _jobs.get(context.scene.name)
        if job is not None:
            job.cancel()
        return {"FINISHED"}


class DrapeSettings(bpy.types.PropertyGroup):
    character: bpy.props.PointerProperty(
        name="Character", type=bpy.types.Object, poll=lambda self, o: o.type == "MESH",
        description="The character's mesh: skinned to an armature, or animated any other way (baked as frames)",
    )
    garments: bpy.props.PointerProperty(
        name="Garments", type=bpy.types.Collection,
        description="The collection of garment meshes, modelled on the character in its bind pose",
    )
    clip: bpy.props.PointerProperty(name="Clip", type=bpy.types.Action, description="The action the armature plays")
    use_scene_range: bpy.props.BoolProperty(name="Scene frame range", default=True)
    frame_start: bpy.props.IntProperty(name="Start", default=1001)
    frame_end: bpy.props.IntProperty(name="End", default=1100)
    preroll_settle: bpy.props.IntProperty(name="Settle", default=20, min=0, description="Pre-roll frames in the bind pose")
    preroll_blend: bpy.props.IntProperty(name="Blend", default=30, min=0, description="Pre-roll frames blending into the clip's first frame")
    preset: bpy.props.EnumProperty(
        name="Accuracy",
        items=[
            ("DRAFT", "Draft", "substeps of 1/600 s (10 a frame at 60 fps, 25 at 24) of 5 iterations"),
            ("STANDARD", "Standard", "substeps of 1/1200 s (20 a frame at 60 fps, 50 at 24) of 10 iterations"),
            ("ACCURATE", "Accurate", "drape chooses the budget per frame: strain under 5 %, penetration under 5 mm (CPU)"),
        ],
        default="STANDARD",
    )
    attach: bpy.props.EnumProperty(
        name="Attach",
        items=[
            ("TOP_EDGE", "Top edge", "each garment's highest particles follow the skin"),
            ("BOTTOM_EDGE", "Bottom edge", "each garment's lowest particles follow the skin"),
            ("NONE", "Nothing", "the garments hang free (a garment's custom property drape_attach overrides)"),
        ],
        default="TOP_EDGE",
    )
    spacing: bpy.props.FloatProperty(name="Spacing", default=0.02, min=0.002, unit="LENGTH", description="Particle spacing of the garments")
    floor: bpy.props.BoolProperty(name="Floor", default=True, description="A ground plane at Blender's Z = 0")
    character_frames: bpy.props.BoolProperty(name="Character frames", default=False, description="Also write the character's frames (OBJ) into the bake")
    output: bpy.props.StringProperty(name="Output", subtype="DIR_PATH", default="//drape")
    progress: bpy.props.FloatProperty(name="Progress", subtype="PERCENTAGE", min=0, max=100)
    status: bpy.props.StringProperty(name="Status")


class DRAPE_PT_panel(bpy.types.Panel):
    bl_label = "drape"
    bl_idname = "DRAPE_PT_panel"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "drape"

    def draw(self, context):
        s = context.scene.drape
        col = self.layout.column()
        col.prop(s, "character")
        col.prop(s, "garments")
        col.prop(s, "clip")
        col.prop(s, "use_scene_range")
        if not s.use_scene_range:
            row = col.row(align=True)
            row.prop(s, "frame_start")
            row.prop(s, "frame_end")
        row = col.row(align=True)
        row.label(text="Pre-roll")
        row.prop(s, "preroll_settle")
        row.prop(s, "preroll_blend")
        col.prop(s, "preset")
        col.prop(s, "attach")
        col.prop(s, "spacing")
        col.prop(s, "floor")
        col.prop(s, "character_frames")
        col.prop(s, "output")
        job = _jobs.get(context.scene.name)
        if job is not None and job.running():
            col.prop(s, "progress", slider=True)
            col.operator("drape.cancel", icon="CANCEL")
        else:
            col.operator("drape.bake", icon="MOD_CLOTH")
            if job is not None:
                col.operator("drape.bake", text="Resume", icon="PLAY").resume = True
        if s.status:
            col.label(text=s.status)


class DrapePreferences(bpy.types.AddonPreferences):
    bl_idname = __name__
    executable: bpy.props.StringProperty(
        name="drape executable", subtype="FILE_PATH",
        description="The drape binary (empty: $DRAPE, then drape on the PATH)",
    )

    def draw(self, context):
        self.layout.prop(self, "executable")


CLASSES = (DrapeSettings, DRAPE_OT_bake, DRAPE_OT_cancel, DRAPE_PT_panel, DrapePreferences)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.drape = bpy.props.PointerProperty(type=DrapeSettings)


def unregister():
    del bpy.types.Scene.drape
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
