#!/usr/bin/env python3
"""Writes a flat-shaded copy of a binary glTF character: every triangle of every mesh gets three
vertices of its own (positions, skin joints and weights, texture coordinates copied from its
corners) and its face normal, as a low-poly asset exported "flat" arrives. The skeleton,
animations, materials and images are kept as they are. drape's tests and benchmarks use the copy
to check that a character split at every edge collides and is measured as its smooth original.

    python3 characters/flat_shade.py characters/CesiumMan/CesiumMan.glb \
        characters/CesiumManFlat/CesiumManFlat.glb

Needs numpy only (the GLB container is read and written here, by the glTF 2.0 specification).
"""

import json
import struct
import sys

import numpy as np

COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
TRIANGLES = 4


def read_glb(path):
    data = open(path, "rb").read()
    magic, version, _ = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67 or version != 2:
        sys.exit(f"{path}: not a binary glTF 2.0 file")
    at, doc, binary = 12, None, b""
    while at < len(data):
        length, kind = struct.unpack_from("<II", data, at)
        chunk = data[at + 8 : at + 8 + length]
        if kind == 0x4E4F534A:
            doc = json.loads(chunk)
        elif kind == 0x004E4942:
            binary = chunk
        at += 8 + length
    return doc, bytearray(binary)


def accessor(doc, binary, index):
    a = doc["accessors"][index]
    view = doc["bufferViews"][a["bufferView"]]
    dtype = np.dtype(COMPONENT[a["componentType"]])
    width = WIDTH[a["type"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    stride = view.get("byteStride", dtype.itemsize * width)
    rows = [
        np.frombuffer(binary, dtype, width, start + k * stride) for k in range(a["count"])
    ]
    return np.array(rows).reshape(a["count"], width)


def append(doc, binary, values, like):
    """Appends `values` as a new accessor shaped like accessor `like`; returns its index."""
    while len(binary) % 4:
        binary.append(0)
    old = doc["accessors"][like]
    raw = np.ascontiguousarray(values.astype(COMPONENT[old["componentType"]])).tobytes()
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(raw)})
    binary.extend(raw)
    new = {
        "bufferView": len(doc["bufferViews"]) - 1,
        "componentType": old["componentType"],
        "count": len(values),
        "type": old["type"],
    }
    if old.get("normalized"):
        new["normalized"] = True
    if "min" in old:
        new["min"] = values.min(axis=0).tolist()
        new["max"] = values.max(axis=0).tolist()
    doc["accessors"].append(new)
    return len(doc["accessors"]) - 1


def flatten(doc, binary):
    for mesh in doc.get("meshes", []):
        for primitive in mesh["primitives"]:
            if primitive.get("mode", TRIANGLES) != TRIANGLES:
                continue
            attributes = primitive["attributes"]
            count = doc["accessors"][attributes["POSITION"]]["count"]
            if "indices" in primitive:
                corners = accessor(doc, binary, primitive.pop("indices")).reshape(-1)
            else:
                corners = np.arange(count)
            positions = accessor(doc, binary, attributes["POSITION"])[corners]
            for name, index in list(attributes.items()):
                if name == "NORMAL":
                    continue
                attributes[name] = append(doc, binary, accessor(doc, binary, index)[corners], index)
            if "NORMAL" in attributes:
                a, b, c = positions[0::3], positions[1::3], positions[2::3]
                normal = np.cross(b - a, c - a)
                length = np.linalg.norm(normal, axis=1, keepdims=True)
                normal = np.where(length > 0, normal / np.maximum(length, 1e-30), [0, 1, 0])
                attributes["NORMAL"] = append(
                    doc, binary, np.repeat(normal, 3, axis=0), attributes["NORMAL"]
                )
            primitive.pop("targets", None)
    doc["buffers"][0]["byteLength"] = len(binary)


def write_glb(path, doc, binary):
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    with open(path, "wb") as out:
        out.write(struct.pack("<III", 0x46546C67, 2, total))
        out.write(struct.pack("<II", len(text), 0x4E4F534A) + text)
        out.write(struct.pack("<II", len(binary), 0x004E4942) + bytes(binary))


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    doc, binary = read_glb(sys.argv[1])
    flatten(doc, binary)
    write_glb(sys.argv[2], doc, binary)


if __name__ == "__main__":
    main()
