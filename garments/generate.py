#!/usr/bin/env python3
"""Writes the garment meshes of this folder (run from anywhere; deterministic output).

cushion.obj: a closed ellipsoid 0.5 x 0.16 x 0.5 m (a solid: drape fills it).
skirt.obj:   an open elliptic cone frustum, waist 0.68 x 0.28 m, hem 0.90 m wide, 0.55 m long
             (a thin sheet: drape voxelizes its surface only).
"""
import math
import os

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
    vertices, uvs, faces = [], [], []
    for r in range(rows + 1):
        t = r / rows
        rx = waist[0] + (hem - waist[0]) * t
        rz = waist[1] + (hem - waist[1]) * t
        for s in range(segments + 1):  # the seam is duplicated so texture coordinates run 0…1
            phi = 2.0 * math.pi * s / segments
            vertices.append((rx * math.cos(phi), -length * t, -rz * math.sin(phi)))
            uvs.append((s / segments, 1.0 - t))
    for r in range(rows):
        for s in range(segments):
            a = r * (segments + 1) + s
            b, c, d = a + 1, a + segments + 1, a + segments + 2
            faces += [(a, c, d), (a, d, b)]
    write("skirt.obj", "skirt: open elliptic cone frustum, waist 0.68 x 0.28 m, hem 0.90 m",
          vertices, uvs, faces)


if __name__ == "__main__":
    cushion()
    skirt()
