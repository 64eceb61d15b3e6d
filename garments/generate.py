#!/usr/bin/env python3
"""Writes the garment meshes of this folder (run from anywhere; deterministic output).

cushion.obj:      a closed ellipsoid 0.5 x 0.16 x 0.5 m (a solid: drape fills it).
skirt.obj:        an open elliptic cone frustum, waist 0.68 x 0.28 m, hem 0.90 m wide, 0.55 m
                  long (a thin sheet: drape voxelizes its surface only).
cesium_skirt.obj: an A-line skirt modelled on CesiumMan's bind pose: an elliptic surface of
                  revolution from his waist to his knees, every ring clear of the body by at
                  least CLEARANCE (read from the character's own bind-pose vertices) but the
                  waistband, which follows the body 1.2 cm off it.
cesium_cape.obj:  a cape down CesiumMan's bind-pose back, from his shoulders to his thighs.
cesium_top.obj:   a top with two sleeves modelled on CesiumMan's bind pose (arms out and down):
                  his own torso and upper arms pushed out 3.5 cm along smoothed normals.
robot_cape.obj:   a cape down RobotExpressive's back in its default node pose (file units: the
                  robot is 4.4 units tall), from under its head to its thighs.

The CesiumMan and robot garments are in the character file's frame (its units, Y up, bind
pose): a scene places them with `"on": "<the character>"`.
"""
import json
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def write(name, header, vertices, uvs, faces):
    with open(os.path.join(HERE, name), "w") as f:
        f.write(f"# {header}\n# written by garments/generate.py\n")
        for v in vertices:
            f.write("v {:.6f} {:.6f} {:.6f}\n".format(*v))
        for t in uvs:
            f.write("vt {:.6f} {:.6f}\n".format(*t))
        for face in faces:
            f.write("f " + " ".join(f"{i + 1}/{i + 1}" for i in face) + "\n")


def grid_faces(rows, columns):
    """Two triangles per cell of a (rows + 1) x (columns + 1) grid of vertices, row by row."""
    faces = []
    for r in range(rows):
        for c in range(columns):
            a = r * (columns + 1) + c
            b, d, e = a + 1, a + columns + 1, a + columns + 2
            faces += [(a, d, e), (a, e, b)]
    return faces


def cushion(segments=32, rings=16, radii=(0.25, 0.08, 0.25)):
    # Poles once each, so every edge is shared by two triangles (closed); the seam shares
    # vertices too (texture coordinates wrap there).
    vertices, uvs, faces = [(0.0, radii[1], 0.0)], [(0.5, 1.0)], []
    for r in range(1, rings):
        theta = math.pi * r / rings
        for s in range(segments):
            phi = 2.0 * math.pi * s / segments
            vertices.append((radii[0] * math.sin(theta) * math.cos(phi),
                             radii[1] * math.cos(theta),
                             -radii[2] * math.sin(theta) * math.sin(phi)))
            uvs.append((s / segments, 1.0 - r / rings))
    vertices.append((0.0, -radii[1], 0.0))
    uvs.append((0.5, 0.0))
    bottom = len(vertices) - 1
    ring = lambda r, s: 1 + (r - 1) * segments + s % segments
    for s in range(segments):
        faces.append((0, ring(1, s), ring(1, s + 1)))
        for r in range(1, rings - 1):
            a, b = ring(r, s), ring(r, s + 1)
            c, d = ring(r + 1, s), ring(r + 1, s + 1)
            faces += [(a, c, d), (a, d, b)]
        faces.append((ring(rings - 1, s), bottom, ring(rings - 1, s + 1)))
    write("cushion.obj", "cushion: closed ellipsoid 0.5 x 0.16 x 0.5 m", vertices, uvs, faces)


def skirt(segments=64, rows=16, waist=(0.34, 0.14), hem=0.45, length=0.55):
    vertices, uvs = [], []
    for r in range(rows + 1):
        t = r / rows
        rx = waist[0] + (hem - waist[0]) * t
        rz = waist[1] + (hem - waist[1]) * t
        for s in range(segments + 1):  # the seam is duplicated so texture coordinates run 0…1
            phi = 2.0 * math.pi * s / segments
            vertices.append((rx * math.cos(phi), -length * t, -rz * math.sin(phi)))
            uvs.append((s / segments, 1.0 - t))
    faces = grid_faces(rows, segments)
    write("skirt.obj", "skirt: open elliptic cone frustum, waist 0.68 x 0.28 m, hem 0.90 m",
          vertices, uvs, faces)


CESIUM = os.path.join(HERE, "..", "characters", "CesiumMan", "CesiumMan.glb")
# Gap between a garment modelled on CesiumMan and his bind-pose skin [m].
CLEARANCE = 0.025


def glb_bind_pose(path):
    """Vertices (bind pose: as stored, placed by the skinned node's parents) and triangles of
    every primitive of a GLB's first mesh. Enough of glTF for CesiumMan: matrices on nodes,
    float positions, unsigned short or int indices."""
    data = open(path, "rb").read()
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + length])
    binary = 20 + length + 8
    parents = {c: i for i, n in enumerate(doc["nodes"]) for c in n.get("children", [])}
    node = next(i for i, n in enumerate(doc["nodes"]) if n.get("mesh") == 0)

    def matrix(n):
        m = doc["nodes"][n].get("matrix", [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])
        return [[m[c * 4 + r] for c in range(4)] for r in range(4)]

    def times(a, b):
        return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]

    place = matrix(node)
    at = node
    while at in parents:
        at = parents[at]
        place = times(matrix(at), place)

    def read(accessor, fmt, width):
        a = doc["accessors"][accessor]
        view = doc["bufferViews"][a["bufferView"]]
        start = binary + view.get("byteOffset", 0) + a.get("byteOffset", 0)
        size = struct.calcsize("<" + fmt)
        return [struct.unpack_from("<" + fmt, data, start + size * i) for i in range(a["count"])]

    vertices, triangles = [], []
    for p in doc["meshes"][0]["primitives"]:
        base = len(vertices)
        for x, y, z in read(p["attributes"]["POSITION"], "3f", 12):
            vertices.append(tuple(place[r][0] * x + place[r][1] * y + place[r][2] * z + place[r][3]
                                  for r in range(3)))
        kind = doc["accessors"][p["indices"]]["componentType"]
        flat = [i[0] for i in read(p["indices"], "H" if kind == 5123 else "I", 0)]
        triangles += [tuple(base + i for i in flat[k:k + 3]) for k in range(0, len(flat), 3)]
    return vertices, triangles


def cesium_skirt(segments=48, rows=16, waist_y=0.95, hem_y=0.45, flare=0.13, band=0.012, band_rows=2):
    """An A-line skirt from CesiumMan's waist to his knees: each ring an ellipse about the
    torso's centre whose radii grow linearly by `flare` from the waist's, and never come
    closer than CLEARANCE to the body's cross-section at that ring's height (the bind-pose
    triangles cut by the ring's plane within |x| < 0.16 m: the torso and the legs; in the bind
    pose the arms reach down beside the hips further out). The waistband follows the body
    instead: the top ring lies `band` outside the cross-section along each ring direction (as
    a waistband sits on the body), and the next `band_rows` rows ease into the ellipses."""
    body, triangles = glb_bind_pose(CESIUM)

    def cut(y):
        segments_at = []
        for t in triangles:
            p = [body[i] for i in t]
            crossing = []
            for a, b in ((p[0], p[1]), (p[1], p[2]), (p[2], p[0])):
                if (a[1] - y) * (b[1] - y) < 0.0:
                    w = (y - a[1]) / (b[1] - a[1])
                    crossing.append((a[0] + w * (b[0] - a[0]), a[2] + w * (b[2] - a[2])))
            if len(crossing) == 2 and all(abs(c[0]) < 0.16 for c in crossing):
                segments_at.append(crossing)
        return segments_at

    def extent(y):
        points = [c for s in cut(y) for c in s]
        xs, zs = [c[0] for c in points], [c[1] for c in points]
        return (max(-min(xs), max(xs)), 0.5 * (max(zs) - min(zs)), 0.5 * (max(zs) + min(zs)))

    def reach(y, centre, phi):
        """How far the cross-section at `y` reaches from (0, centre) along the ring direction
        `phi`: the farthest crossing of that ray with the cut."""
        dx, dz = math.cos(phi), -math.sin(phi)
        farthest = 0.0
        for (ax, az), (bx, bz) in cut(y):
            az, bz = az - centre, bz - centre
            ex, ez = bx - ax, bz - az
            den = dx * ez - dz * ex
            if abs(den) < 1e-12:
                continue
            t, u = (ax * ez - az * ex) / den, (ax * dz - az * dx) / den
            if t > 0.0 and 0.0 <= u <= 1.0:
                farthest = max(farthest, t)
        return farthest

    wx, wz, centre = extent(waist_y)
    vertices, uvs = [], []
    for r in range(rows + 1):
        t = r / rows
        y = waist_y + (hem_y - waist_y) * t
        ex, ez, _ = extent(y)
        rx = max(wx + CLEARANCE + flare * t, ex + CLEARANCE)
        rz = max(wz + CLEARANCE + flare * t, ez + CLEARANCE)
        for s in range(segments + 1):  # the seam is duplicated so texture coordinates run 0…1
            phi = 2.0 * math.pi * s / segments
            x, z = rx * math.cos(phi), centre - rz * math.sin(phi)
            if r < band_rows:
                on_body = reach(y, centre, phi) + band
                bx, bz = on_body * math.cos(phi), centre - on_body * math.sin(phi)
                e = r / band_rows
                x, z = bx + (x - bx) * e, bz + (z - bz) * e
            vertices.append((x, y, z))
            uvs.append((s / segments, 1.0 - t))
    faces = grid_faces(rows, segments)
    write("cesium_skirt.obj",
          f"cesium_skirt: A-line skirt on CesiumMan's bind pose, waist y {waist_y} m, hem y {hem_y} m, "
          f"waistband {band} m off the body",
          vertices, uvs, faces)


def cesium_top(bottom=0.84, neck=1.09, cuff=0.36, clearance=0.035):
    """A top with two sleeves: CesiumMan's bind-pose torso (from `bottom` up to `neck`) and
    upper arms (out to |x| = `cuff`), welded by position and pushed out by `clearance` along
    the angle-weighted vertex normals, smoothed. Open at the hem, the neck and the cuffs."""
    body, triangles = glb_bind_pose(CESIUM)
    index, welded = {}, []
    remap = []
    for v in body:
        key = tuple(round(c, 6) for c in v)
        if key not in index:
            index[key] = len(welded)
            welded.append(v)
        remap.append(index[key])
    faces = [tuple(remap[i] for i in t) for t in triangles]
    faces = [f for f in faces if len(set(f)) == 3]
    normals = [[0.0, 0.0, 0.0] for _ in welded]

    def sub(a, b):
        return [a[k] - b[k] for k in range(3)]

    def cross(a, b):
        return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

    def unit(a):
        n = math.sqrt(sum(c * c for c in a)) or 1.0
        return [c / n for c in a]

    for f in faces:
        p = [welded[i] for i in f]
        n = unit(cross(sub(p[1], p[0]), sub(p[2], p[0])))
        for k in range(3):
            e1, e2 = unit(sub(p[(k + 1) % 3], p[k])), unit(sub(p[(k + 2) % 3], p[k]))
            angle = math.acos(max(-1.0, min(1.0, sum(e1[c] * e2[c] for c in range(3)))))
            for c in range(3):
                normals[f[k]][c] += angle * n[c]
    # Averaged over their neighbours 20 times, the directions no longer converge in his
    # armpits, where a surface pushed out along the body's own normals passes through itself
    # (44 pairs of its triangles did before 2026-12-05).
    ring = [set() for _ in welded]
    for f in faces:
        for k in range(3):
            ring[f[k]].update((f[(k + 1) % 3], f[(k + 2) % 3]))
    normals = [unit(n) for n in normals]
    for _ in range(20):
        normals = [unit([normals[i][c] + sum(normals[j][c] for j in ring[i]) / max(1, len(ring[i]))
                         for c in range(3)]) for i in range(len(welded))]
    inside = lambda v: bottom <= v[1] <= neck and abs(v[0]) <= cuff
    kept = [f for f in faces if all(inside(welded[i]) for i in f)]
    used = sorted({i for f in kept for i in f})
    new = {old: k for k, old in enumerate(used)}
    vertices = []
    for i in used:
        n = unit(normals[i])
        vertices.append(tuple(welded[i][c] + clearance * n[c] for c in range(3)))
    uvs = [(0.5 + v[0] / (2 * cuff), (v[1] - bottom) / (neck - bottom)) for v in vertices]
    write("cesium_top.obj",
          f"cesium_top: CesiumMan's bind-pose torso and upper arms pushed out {clearance} m",
          vertices, uvs, [tuple(new[i] for i in f) for f in kept])


def cesium_cape(columns=15, rows=23, collar=0.07, half_width=0.17, top=1.06, bottom=0.6,
                curl=1.5):
    """A cape down CesiumMan's back (his front is +Z): a trapezoid from a collar `collar`
    either side of his spine at shoulder height (inside his shoulders, which the arms move)
    to `half_width` either side at his thighs, bent round his back (z rises by `curl` x^2
    towards the edges), every point CLEARANCE behind the deepest bind-pose vertex of the torso
    and legs at its height."""
    body, _ = glb_bind_pose(CESIUM)
    back = [v for v in body if abs(v[0]) <= half_width + 0.03]
    vertices, uvs = [], []
    for r in range(rows + 1):
        y = top + (bottom - top) * r / rows
        near = [v[2] for v in back if abs(v[1] - y) <= 0.04] or [v[2] for v in back]
        z0 = min(near) - CLEARANCE
        half = collar + (half_width - collar) * r / rows
        for c in range(columns + 1):
            x = -half + 2.0 * half * c / columns
            vertices.append((x, y, z0 + curl * x * x))
            uvs.append((c / columns, 1.0 - r / rows))
    faces = grid_faces(rows, columns)
    write("cesium_cape.obj",
          f"cesium_cape: a cape down CesiumMan's bind-pose back, {2 * collar} to {2 * half_width} m wide",
          vertices, uvs, faces)


ROBOT = os.path.join(HERE, "..", "characters", "RobotExpressive", "RobotExpressive.glb")


def glb_node_mesh(path, name):
    """Vertices and triangles of the mesh on the node called `name` in a GLB, placed by the
    node's and its parents' default transforms (translation, rotation, scale or a matrix)."""
    data = open(path, "rb").read()
    length = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + length])
    binary = 20 + length + 8
    parents = {c: i for i, n in enumerate(doc["nodes"]) for c in n.get("children", [])}

    def local(n):
        node = doc["nodes"][n]
        if "matrix" in node:
            m = node["matrix"]
            return [[m[c * 4 + r] for c in range(4)] for r in range(4)]
        t = node.get("translation", [0, 0, 0])
        x, y, z, w = node.get("rotation", [0, 0, 0, 1])
        s = node.get("scale", [1, 1, 1])
        rot = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
               [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
               [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        return [[rot[r][0] * s[0], rot[r][1] * s[1], rot[r][2] * s[2], t[r]] for r in range(3)] + [[0, 0, 0, 1]]

    def times(a, b):
        return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]

    node = next(i for i, n in enumerate(doc["nodes"]) if n.get("name") == name and "mesh" in n)
    place, at = local(node), node
    while at in parents:
        at = parents[at]
        place = times(local(at), place)

    def read(accessor, fmt):
        a = doc["accessors"][accessor]
        view = doc["bufferViews"][a["bufferView"]]
        start = binary + view.get("byteOffset", 0) + a.get("byteOffset", 0)
        size = struct.calcsize("<" + fmt)
        stride = view.get("byteStride", size)
        return [struct.unpack_from("<" + fmt, data, start + stride * i) for i in range(a["count"])]

    vertices, triangles = [], []
    for p in doc["meshes"][doc["nodes"][node]["mesh"]]["primitives"]:
        base = len(vertices)
        for x, y, z in read(p["attributes"]["POSITION"], "3f"):
            vertices.append(tuple(place[r][0] * x + place[r][1] * y + place[r][2] * z + place[r][3]
                                  for r in range(3)))
        kind = doc["accessors"][p["indices"]]["componentType"]
        flat = [i[0] for i in read(p["indices"], "H" if kind == 5123 else "I")]
        triangles += [tuple(base + i for i in flat[k:k + 3]) for k in range(0, len(flat), 3)]
    return vertices, triangles


def behind(vertices, triangles, x, y):
    """The smallest z of the surface over (x, y) (its back, seen along +z), or None."""
    best = None
    for t in triangles:
        a, b, c = (vertices[i] for i in t)
        d = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1])
        if abs(d) < 1e-12:
            continue
        l1 = ((b[1] - c[1]) * (x - c[0]) + (c[0] - b[0]) * (y - c[1])) / d
        l2 = ((c[1] - a[1]) * (x - c[0]) + (a[0] - c[0]) * (y - c[1])) / d
        l3 = 1.0 - l1 - l2
        if min(l1, l2, l3) >= 0.0:
            z = l1 * a[2] + l2 * b[2] + l3 * c[2]
            best = z if best is None else min(best, z)
    return best


def robot_cape(columns=14, rows=22, collar=0.35, half_width=0.55, top=2.6, bottom=1.05,
               clearance=0.13):
    """A cape down RobotExpressive's back (its front is +Z), in file units: a trapezoid from a
    collar `collar` either side of its spine under its head to `half_width` either side at its
    thighs, every point `clearance` (2.6 cm at the 0.2 scale its scene uses) behind the torso's
    back along -Z; past the widest point of the back (its hips) the cape falls straight."""
    torso, triangles = glb_node_mesh(ROBOT, "Torso")
    vertices, uvs, above = [], [], None
    for r in range(rows + 1):
        y = top + (bottom - top) * r / rows
        half = collar + (half_width - collar) * r / rows
        xs = [-half + 2.0 * half * c / columns for c in range(columns + 1)]
        row = []
        for c, x in enumerate(xs):
            z = behind(torso, triangles, x, y)
            z = None if z is None else z - clearance
            if above is not None and (z is None or z > above[c]):
                z = above[c]
            row.append(z)
        known = [z for z in row if z is not None]
        row = [min(known) if z is None else z for z in row]
        above = row
        for c, x in enumerate(xs):
            vertices.append((x, y, row[c]))
            uvs.append((c / columns, 1.0 - r / rows))
    write("robot_cape.obj",
          f"robot_cape: a cape down RobotExpressive's back, {2 * collar} to {2 * half_width} units wide",
          vertices, uvs, grid_faces(rows, columns))


if __name__ == "__main__":
    cushion()
    skirt()
    cesium_skirt()
    cesium_top()
    cesium_cape()
    robot_cape()
