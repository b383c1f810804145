#!/usr/bin/env python3
"""Regenerates the seed corpus of the fuzz targets (tests/fuzz/corpus/<target>/).

Text seeds come from small pieces of ../shared/scenes (trimmed so that every seed stays under
~8 KB: libFuzzer's default input length follows the largest seed) and from hand-written files
that use every statement each format knows; binary seeds (protocol messages, scenes as wire
bytes, tile pixels) are written by the fuzz_make_seeds program with rtc's own encoders.

Usage: tests/fuzz/make_corpus.py [--build build/release]   (builds fuzz_make_seeds if needed)
"""
import argparse
import base64
import json
import os
import re
import shutil
import struct
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
SHARED = os.path.normpath(os.path.join(ROOT, "..", "shared", "scenes"))
TEMPORAL = os.path.join(ROOT, "tests", "temporal", "scenes")


def write(target, name, data):
    folder = os.path.join(HERE, "corpus", target)
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def read(path):
    with open(path, "rb") as f:
        return f.read()


def trimmed_obj(path, faces):
    """The first `faces` faces of an OBJ with the vertices they use renumbered (1-based), the
    usemtl lines in between kept, and `mtllib m.mtl`."""
    verts, out_faces, used, order = [], [], {}, []
    for line in read(path).decode(errors="replace").splitlines():
        if line.startswith("v "):
            verts.append(line)
        elif line.startswith("usemtl"):
            out_faces.append(line)
        elif line.startswith("f ") and sum(1 for f in out_faces if f.startswith("f ")) < faces:
            idx = []
            for tok in line.split()[1:]:
                v = int(tok.split("/")[0])
                v = v if v > 0 else len(verts) + 1 + v
                if v not in used:
                    used[v] = len(order) + 1
                    order.append(v)
                idx.append(str(used[v]))
            out_faces.append("f " + " ".join(idx))
    lines = ["mtllib m.mtl"] + [verts[v - 1] for v in order] + out_faces
    return "\n".join(lines) + "\n"


CUBE_MTL = """# every statement the MTL reader knows
newmtl red
Kd 0.8 0.1 0.1
Ks 0.2 0.2 0.2
Ns 40
d 1
illum 2
newmtl glass
Kd 0.1 0.1 0.1
Ks 0.9 0.9 0.9
Ns 900
illum 3
Ke 0.5 0.5 0.5
Tr 0.25
newmtl grey
Kd 0.5
"""

OBJ_FORMS = """# v, v/t, v//n, v/t/n, negative indices, a polygon, skipped statements
mtllib m.mtl
o thing
g group
s 1
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0 1.0
v 0.5 0.5 1 0.2 0.3 0.4
vt 0 0
vt 1 0
vt 1 1
vn 0 0 1
vn 0 1 0
usemtl red
f 1 2 3
f 1/1 3/2 4/3
f 1//1 2//2 5//1
f 1/1/1 2/2/2 3/3/1 4/1/2
usemtl glass
f -1 -2 -3
l 1 2
p 3
#--mtl--
""" + CUBE_MTL


def ply(fmt, with_extras=False):
    verts = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    header = ["ply", f"format {fmt} 1.0", "comment rtc fuzz seed", f"element vertex {len(verts)}",
              "property float x", "property float y", "property float z"]
    if with_extras:
        header += ["property float nx", "property float ny", "property float nz",
                   "property uchar red", "property uchar green", "property uchar blue"]
    header += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
    if with_extras:
        header += ["element edge 1", "property int vertex1", "property int vertex2"]
    header += ["end_header"]
    head = ("\n".join(header) + "\n").encode()
    if fmt == "ascii":
        body = ""
        for v in verts:
            body += " ".join(str(c) for c in v) + (" 0 0 1 255 128 0" if with_extras else "") + "\n"
        for f in faces:
            body += "3 " + " ".join(str(i) for i in f) + "\n"
        if with_extras:
            body += "0 1\n"
        return head + body.encode()
    e = "<" if fmt == "binary_little_endian" else ">"
    body = b""
    for v in verts:
        body += struct.pack(e + "3f", *v)
        if with_extras:
            body += struct.pack(e + "3f3B", 0, 0, 1, 255, 128, 0)
    for f in faces:
        body += struct.pack(e + "B3i", 3, *f)
    if with_extras:
        body += struct.pack(e + "2i", 0, 1)
    return head + body


NFF_ALL = """# every primitive and statement of NFF (SPD 3.14 and NFF.TXT)
b 0.1 0.2 0.3
v
from 2 1.5 3
at 0 0 0
up 0 1 0
angle 40
hither 0.01
resolution 64 48
l 4 3 2
l -3 5 1 0.5 0.5 0.5
f 0.8 0.2 0.2 0.7 0.3 20 0 1
s 0 0 0 0.5
f 0.2 0.8 0.2 1 0 0 0 1
c
0 -1 0 0.3
0 1 0 0.1
c 1 0 0 0.2 1 1 0 0.2
p 3
-2 -1 -2
2 -1 -2
2 -1 2
pp 3
-1 0 -1 0 1 0
1 0 -1 0 1 0
0 0 1 0 1 0
p 4
-2 -1 2
2 -1 2
2 1 2
-2 1 2
"""


def first_nff_lines(path, primitives):
    out, count, lines = [], 0, read(path).decode().splitlines()
    i = 0
    while i < len(lines) and count < primitives:
        out.append(lines[i])
        if lines[i].split()[:1] in (["s"], ["p"], ["pp"], ["c"]):
            count += 1
        i += 1
    # finish a polygon's vertex lines
    while i < len(lines) and re.match(r"^\s*-?[0-9.]", lines[i]):
        out.append(lines[i])
        i += 1
    return "\n".join(out) + "\n"


def gltf_seeds():
    src = os.path.join(SHARED, "gltf-samples", "BoxTextured.gltf")
    doc = json.loads(read(src))
    buf = read(os.path.join(SHARED, "gltf-samples", doc["buffers"][0]["uri"]))
    # images are not read (materials use baseColorFactor): drop them to keep the seed small
    doc.pop("images", None)
    doc.pop("textures", None)
    doc.pop("samplers", None)
    for m in doc.get("materials", []):
        m.get("pbrMetallicRoughness", {}).pop("baseColorTexture", None)
    embedded = json.loads(json.dumps(doc))
    embedded["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(buf).decode()
    write("gltf", "box-embedded.gltf", json.dumps(embedded, indent=1))
    # the same as .glb: header, JSON chunk, BIN chunk (4-byte aligned)
    glb_doc = json.loads(json.dumps(doc))
    glb_doc["buffers"][0].pop("uri")
    js = json.dumps(glb_doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    binary = buf + b"\0" * (-len(buf) % 4)
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(binary), b"BIN\0") + binary
    write("gltf", "box.glb", struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)
    # one triangle, two nodes instancing it (a scaled and rotated child)
    tri = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<3H", 0, 1, 2) + b"\0\0"
    write("gltf", "instanced-triangle.gltf", json.dumps({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "children": [1]},
                  {"mesh": 0, "translation": [2, 0, 0], "rotation": [0, 0.7071068, 0, 0.7071068], "scale": [2, 2, 2]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.1, 1]}, "emissiveFactor": [0, 0, 0.1]}],
        "buffers": [{"byteLength": len(tri), "uri": "data:application/octet-stream;base64," + base64.b64encode(tri).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
    }, indent=1))


def scene_json_seeds():
    for path in sorted(os.listdir(TEMPORAL)):
        if not path.endswith(".json"):
            continue
        doc = json.loads(read(os.path.join(TEMPORAL, path)))
        doc.pop("notes", None)
        for mesh in doc.get("meshes", []):
            mesh["file"] = "cube.obj"  # the one mesh the fuzz target's scratch folder holds
        write("scene_json", path, json.dumps(doc, indent=1))
    # every optional field of docs/scene-format.md at least once
    write("scene_json", "all-fields.json", json.dumps({
        "name": "all", "meshes": [{"file": "cube.obj", "name": "a", "material": "m",
                                    "transform": {"translate": [1, 2, 3], "rotate_deg_axis": [30, 0, 1, 0], "scale": [1, 2, 1]}},
                                   {"file": "cube.obj", "name": "b", "transform": {"scale": 0.5}}],
        "materials": [{"name": "m", "diffuse": [0.5, 0.4, 0.3], "specular": [0.2, 0.2, 0.2], "shininess": 30,
                       "reflective": True, "emission": [0, 0, 0]}],
        "camera": {"eye": [0, 2, 8], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 45},
        "lights": [{"position": [3, 5, 2], "color": [1, 1, 1]}],
        "resolution": [64, 48], "background": [0.1, 0.1, 0.2], "ambient": [0.05, 0.05, 0.05],
        "render": {"max_depth": 3, "min_weight": 0.01, "spp": 2, "intersector": "watertight"},
        "animation": {"frames": [0, 4],
                      "camera": [{"frame": 0, "eye": [0, 2, 8], "look_at": [0, 0, 0]}, {"frame": 4, "eye": [1, 2, 8], "look_at": [0, 0, 0]}],
                      "meshes": [{"mesh": "b", "keys": [{"frame": 0, "translate": [0, 0, 0]},
                                                        {"frame": 4, "translate": [1, 0, 0], "rotate_deg_axis": [90, 0, 1, 0]}]}],
                      "lights": [{"light": 0, "keys": [{"frame": 0, "position": [3, 5, 2]}, {"frame": 4, "position": [-3, 5, 2]}]}]},
    }, indent=1))
    write("scene_json", "bare-minimum.json", '{"meshes": [{"file": "cube.obj"}]}\n')


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build", "release"))
    args = ap.parse_args()
    if not os.path.isdir(SHARED):
        sys.exit(f"make_corpus: {SHARED} is missing (the shared scene pack)")
    corpus = os.path.join(HERE, "corpus")
    shutil.rmtree(corpus, ignore_errors=True)

    write("obj", "forms.obj", OBJ_FORMS)
    write("obj", "cube-red.obj", "mtllib m.mtl\nusemtl red\n" + read(os.path.join(TEMPORAL, "cube.obj")).decode() + "#--mtl--\n" + CUBE_MTL)
    write("obj", "quad.obj", read(os.path.join(TEMPORAL, "quad.obj")))
    write("obj", "bunny-40.obj", trimmed_obj(os.path.join(SHARED, "bunny", "bunny.obj"), 40) + "#--mtl--\n" +
          read(os.path.join(SHARED, "bunny", "bunny.mtl")).decode())
    write("obj", "office-60.obj", trimmed_obj(os.path.join(SHARED, "radiance-office", "radiance-office.obj"), 60) +
          "#--mtl--\n" + read(os.path.join(SHARED, "radiance-office", "radiance-office.mtl")).decode())
    for fmt in ("ascii", "binary_little_endian", "binary_big_endian"):
        write("ply", f"tetra-{fmt}.ply", ply(fmt))
        write("ply", f"tetra-{fmt}-extras.ply", ply(fmt, True))
    write("nff", "all-primitives.nff", NFF_ALL)
    write("nff", "balls-s3-head.nff", first_nff_lines(os.path.join(SHARED, "spd-balls-s3", "spd-balls-s3.nff"), 12))
    gltf_seeds()
    scene_json_seeds()

    seeds = os.path.join(args.build, "tests", "fuzz", "fuzz_make_seeds")
    if not os.path.exists(seeds):
        subprocess.run(["cmake", "--build", args.build, "--target", "fuzz_make_seeds"], check=True)
    subprocess.run([seeds, corpus] + [os.path.join(TEMPORAL, f) for f in ("quad.obj", "cube.obj", "moving_light.json")],
                   check=True)
    for target in sorted(os.listdir(corpus)):
        files = os.listdir(os.path.join(corpus, target))
        size = sum(os.path.getsize(os.path.join(corpus, target, f)) for f in files)
        print(f"make_corpus: {target}: {len(files)} seeds, {size} bytes")


if __name__ == "__main__":
    main()
