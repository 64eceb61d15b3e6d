"""Reads an Alembic cache with the official library (PyAlembic, `alembic3d` from PyPI) and
compares every sample of every mesh with the OBJ frames drape wrote beside it.

    python alembic_check.py CACHE.abc OBJ_DIR

Prints one JSON object: the archive's time samplings, each rope's curve against its OBJ
polyline, and, per mesh (named by its Xform), the
number of samples, their times, whether its faces are constant, and the worst differences
from the OBJ frames (positions, UVs, normals, in their units) and how many samples' faces
differ from the OBJ's. Faces: Alembic's are clockwise, so each face is read backwards.
"""
import json
import math
import os
import sys

import alembic3d
from alembic3d import Abc, AbcGeom


def obj_frame(path):
    v, vt, vn, faces = [], [], [], []
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "v":
                v.append(tuple(map(float, w[1:4])))
            elif w[0] == "vt":
                vt.append(tuple(map(float, w[1:3])))
            elif w[0] == "vn":
                vn.append(tuple(map(float, w[1:4])))
            elif w[0] == "f":
                faces.append(tuple(int(c.split("/")[0]) - 1 for c in w[1:]))
    return v, vt, vn, faces


def objects(obj, schema, found):
    """Every object under `obj` whose metadata `schema` (IPolyMesh, ICurves) matches."""
    for child in obj.children:
        if schema.matches(child.getMetaData()):
            found.append(child)
        objects(child, schema, found)
    return found


def check_curves(archive, obj_dir, out):
    """A rope: one linear, open curve through its vertices, each sample its OBJ frame."""
    for curve in objects(archive.getTop(), AbcGeom.ICurves, []):
        schema = AbcGeom.ICurves(curve.getParent(), curve.getName()).getSchema()
        name = curve.getParent().getName()
        ts = schema.getTimeSampling()
        n = schema.getNumSamples()
        fps = 1.0 / ts.getTimeSamplingType().getTimePerCycle()
        r = {"path": curve.getFullName(), "samples": n, "first_time": ts.getSampleTime(0),
             "last_time": ts.getSampleTime(n - 1), "position_worst": 0.0, "kinds": []}
        for k in range(n):
            t = ts.getSampleTime(k)
            s = schema.getValue(Abc.ISampleSelector(t, Abc.ISampleSelector.TimeIndexType.kNearIndex))
            v = obj_frame(os.path.join(obj_dir, "%s_%04d.obj" % (name, round(t * fps))))[0]
            p = s.getPositions()
            assert len(p) == len(v), (name, k)
            r["position_worst"] = max(
                [r["position_worst"]] + [math.dist((a[0], a[1], a[2]), b) for a, b in zip(p, v)]
            )
            kind = "%s %s %s" % (s.getType(), s.getWrap(), list(s.getCurvesNumVertices()))
            if kind not in r["kinds"]:
                r["kinds"].append(kind)
        out["curves"][name] = r


def check(path, obj_dir):
    archive = Abc.IArchive(path)
    out = {"time_samplings": [], "meshes": {}, "curves": {}}
    for i in range(archive.getNumTimeSamplings()):
        ts = archive.getTimeSampling(i)
        out["time_samplings"].append(
            {"step": ts.getTimeSamplingType().getTimePerCycle(), "start": ts.getSampleTime(0)}
        )
    for mesh in objects(archive.getTop(), AbcGeom.IPolyMesh, []):
        schema = AbcGeom.IPolyMesh(mesh.getParent(), mesh.getName()).getSchema()
        name = mesh.getParent().getName()
        ts = schema.getTimeSampling()
        n = schema.getNumSamples()
        fps = 1.0 / ts.getTimeSamplingType().getTimePerCycle()
        uv_param = schema.getUVsParam()
        n_param = schema.getNormalsParam()
        r = {
            "path": mesh.getFullName(),
            "samples": n,
            "first_time": ts.getSampleTime(0),
            "last_time": ts.getSampleTime(n - 1),
            "constant_faces": schema.getTopologyVariance()
            != AbcGeom.MeshTopologyVariance.kHeterogenousTopology,
            "uv_scope": str(uv_param.getScope()) if uv_param.valid() else None,
            "normal_scope": str(n_param.getScope()) if n_param.valid() else None,
            "position_worst": 0.0,
            "bounds_worst": 0.0,
            "uv_worst": 0.0,
            "normal_worst": 0.0,
            "faces_differ": 0,
            "faces": [],
        }
        for k in range(n):
            # By time: the binding takes an int for a time too.
            sel = Abc.ISampleSelector(
                ts.getSampleTime(k), Abc.ISampleSelector.TimeIndexType.kNearIndex
            )
            s = schema.getValue(sel)
            frame = round(ts.getSampleTime(k) * fps)
            # A still mesh (a character that does not move) has its first frame's OBJ only.
            at = frame
            while not os.path.exists(os.path.join(obj_dir, "%s_%04d.obj" % (name, at))) and at > 0:
                at -= 1
            v, vt, vn, faces = obj_frame(os.path.join(obj_dir, "%s_%04d.obj" % (name, at)))
            p = s.getPositions()
            assert len(p) == len(v), (name, k, len(p), len(v))
            worst = 0.0
            for a, b in zip(p, v):
                worst = max(worst, math.dist((a[0], a[1], a[2]), b))
            r["position_worst"] = max(r["position_worst"], worst)
            box = s.getSelfBounds()
            lo = [min(c[i] for c in v) for i in range(3)]
            hi = [max(c[i] for c in v) for i in range(3)]
            r["bounds_worst"] = max(
                r["bounds_worst"],
                max(abs(box.min()[i] - lo[i]) for i in range(3)),
                max(abs(box.max()[i] - hi[i]) for i in range(3)),
            )
            counts, indices = s.getFaceCounts(), s.getFaceIndices()
            read, at = [], 0
            for c in counts:
                read.append(tuple(indices[at + c - 1 - j] for j in range(c)))
                at += c
            r["faces"].append(len(read))
            if read != faces:
                r["faces_differ"] += 1
            if uv_param.valid():
                uv = uv_param.getIndexedValue(sel)
                vals, idx = uv.getVals(), uv.getIndices()
                # Face-varying: one index per face corner, in Alembic's (reversed) corner order.
                at = 0
                for face in read:
                    for j in range(len(face)):
                        u = vals[idx[at + len(face) - 1 - j]]
                        want = vt[face[j]]
                        r["uv_worst"] = max(r["uv_worst"], math.dist((u[0], u[1]), want))
                    at += len(face)
            if n_param.valid():
                normals = n_param.getExpandedValue(sel).getVals()
                for a, b in zip(normals, vn):
                    r["normal_worst"] = max(r["normal_worst"], math.dist((a[0], a[1], a[2]), b))
        out["meshes"][name] = r
    check_curves(archive, obj_dir, out)
    return out


if __name__ == "__main__":
    print(json.dumps(check(sys.argv[1], sys.argv[2])))
