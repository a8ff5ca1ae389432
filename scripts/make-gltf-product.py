#!/usr/bin/env python3
"""Writes scenes/product/product.glb: a small product shot in glTF 2.0, made here so that its
source is this script. A tiled floor (an embedded PNG repeated 3x3 by KHR_texture_transform)
before a pale backdrop; a gold sphere, a solid glass sphere (KHR_materials_transmission, _ior
and _volume) placed by two nodes from the same vertex data, a red box turned 30 degrees, all under an
emissive panel (KHR_materials_emissive_strength) and a spot light (KHR_lights_punctual); a
perspective camera. Every mesh has normals and texture coordinates.

Usage: python3 scripts/make-gltf-product.py scenes/product
"""
import json
import math
import struct
import sys
import zlib
from pathlib import Path


def png_bytes(width, height, pixel):
    rows = bytearray()
    for y in range(height):
        rows.append(0)
        for x in range(width):
            rows.extend(pixel(x, y))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"sRGB", b"\x00") +
            chunk(b"IDAT", zlib.compress(bytes(rows), 9)) + chunk(b"IEND", b""))


def tile(x, y):
    """64x64 texels: four stone tiles with a thin dark grout."""
    if x % 32 < 2 or y % 32 < 2:
        return (60, 55, 50)
    shade = 200 if ((x // 32) + (y // 32)) % 2 == 0 else 170
    return (shade, shade - 12, shade - 30)


class Writer:
    def __init__(self):
        self.bin = bytearray()
        self.doc = {"asset": {"version": "2.0", "generator": "rayfarm scripts/make-gltf-product.py"},
                    "bufferViews": [], "accessors": [], "meshes": [], "nodes": [],
                    "materials": []}

    def view(self, data):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": len(self.bin),
                                        "byteLength": len(data)})
        self.bin.extend(data)
        return len(self.doc["bufferViews"]) - 1

    def floats(self, values, kind, n):
        acc = {"bufferView": self.view(struct.pack("<%df" % len(values), *values)),
               "componentType": 5126, "count": len(values) // n, "type": kind}
        if kind == "VEC3" and n == 3:
            acc["min"] = [min(values[i::3]) for i in range(3)]
            acc["max"] = [max(values[i::3]) for i in range(3)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def indices(self, values):
        self.doc["accessors"].append({"bufferView": self.view(struct.pack("<%dI" % len(values), *values)),
                                      "componentType": 5125, "count": len(values), "type": "SCALAR"})
        return len(self.doc["accessors"]) - 1

    def geometry(self, pos, nor, uv, idx):
        return {"POSITION": self.floats(pos, "VEC3", 3), "NORMAL": self.floats(nor, "VEC3", 3),
                "TEXCOORD_0": self.floats(uv, "VEC2", 2)}, self.indices(idx)

    def mesh(self, name, attributes, indices, material):
        self.doc["meshes"].append({"name": name, "primitives": [
            {"attributes": attributes, "indices": indices, "material": material}]})
        return len(self.doc["meshes"]) - 1

    def material(self, m):
        self.doc["materials"].append(m)
        return len(self.doc["materials"]) - 1

    def node(self, n):
        self.doc["nodes"].append(n)
        return len(self.doc["nodes"]) - 1


def quad(size_x, size_z):
    """A quad in y = 0 facing +y, centred on the origin."""
    x, z = size_x / 2, size_z / 2
    pos = [-x, 0, z, x, 0, z, x, 0, -z, -x, 0, -z]
    return pos, [0, 1, 0] * 4, [0, 1, 1, 1, 1, 0, 0, 0], [0, 1, 2, 0, 2, 3]


def sphere(rings=24, segments=48):
    pos, nor, uv, idx = [], [], [], []
    for r in range(rings + 1):
        theta = math.pi * r / rings
        for s in range(segments + 1):
            phi = 2 * math.pi * s / segments
            p = (math.sin(theta) * math.cos(phi), math.cos(theta), -math.sin(theta) * math.sin(phi))
            pos += p
            nor += p
            uv += [s / segments, r / rings]
    for r in range(rings):
        for s in range(segments):
            a = r * (segments + 1) + s
            b = a + segments + 1
            idx += [a, b, a + 1, a + 1, b, b + 1]
    return pos, nor, uv, idx


def box():
    pos, nor, uv, idx = [], [], [], []
    for axis in range(3):
        for sign in (1, -1):
            n = [0, 0, 0]
            n[axis] = sign
            u = [0, 0, 0]
            u[(axis + 1) % 3] = 1
            v = [0, 0, 0]
            v[(axis + 2) % 3] = 1
            if sign < 0:
                u, v = v, u
            base = len(pos) // 3
            for du, dv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                pos += [0.5 * (n[i] + du * u[i] + dv * v[i]) for i in range(3)]
                nor += n
                uv += [(du + 1) / 2, (dv + 1) / 2]
            idx += [base, base + 1, base + 2, base, base + 2, base + 3]
    return pos, nor, uv, idx


def look_rotation(eye, target):
    """Quaternion (x, y, z, w) turning -z towards target and keeping +y up."""
    f = [t - e for t, e in zip(target, eye)]
    fl = math.sqrt(sum(c * c for c in f))
    f = [c / fl for c in f]
    z = [-c for c in f]
    up = [0, 1, 0]
    x = [up[1] * z[2] - up[2] * z[1], up[2] * z[0] - up[0] * z[2], up[0] * z[1] - up[1] * z[0]]
    xl = math.sqrt(sum(c * c for c in x))
    x = [c / xl for c in x]
    y = [z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]]
    m = [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]]
    w = math.sqrt(max(0.0, 1 + m[0][0] + m[1][1] + m[2][2])) / 2
    return [(m[2][1] - m[1][2]) / (4 * w), (m[0][2] - m[2][0]) / (4 * w),
            (m[1][0] - m[0][1]) / (4 * w), w]


def main(folder):
    w = Writer()
    image = w.view(png_bytes(64, 64, tile))
    w.doc["images"] = [{"bufferView": image, "mimeType": "image/png", "name": "tiles"}]
    w.doc["samplers"] = [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
    w.doc["textures"] = [{"source": 0, "sampler": 0}]
    floor_m = w.material({"name": "tiles", "pbrMetallicRoughness": {
        "baseColorTexture": {"index": 0, "extensions": {
            "KHR_texture_transform": {"scale": [3, 3]}}},
        "metallicFactor": 0.0, "roughnessFactor": 0.7}})
    wall_m = w.material({"name": "backdrop", "pbrMetallicRoughness": {
        "baseColorFactor": [0.7, 0.72, 0.75, 1], "metallicFactor": 0.0, "roughnessFactor": 1.0}})
    gold_m = w.material({"name": "gold", "pbrMetallicRoughness": {
        "baseColorFactor": [1.0, 0.78, 0.34, 1], "metallicFactor": 1.0, "roughnessFactor": 0.25}})
    glass_m = w.material({"name": "glass", "pbrMetallicRoughness": {
        "baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0.0, "roughnessFactor": 0.0},
        # A volume makes the transmitting surface the boundary of solid glass rather than a thin
        # wall; the thickness is the sphere's diameter in the mesh's own units.
        "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                       "KHR_materials_ior": {"ior": 1.5},
                       "KHR_materials_volume": {"thicknessFactor": 2.0}}})
    red_m = w.material({"name": "red plastic", "pbrMetallicRoughness": {
        "baseColorFactor": [0.7, 0.08, 0.06, 1], "metallicFactor": 0.0, "roughnessFactor": 0.4}})
    lamp_m = w.material({"name": "lamp", "emissiveFactor": [1.0, 0.95, 0.9],
                         "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]},
                         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 6}}})

    floor_a, floor_i = w.geometry(*quad(6, 6))
    sphere_a, sphere_i = w.geometry(*sphere())
    box_a, box_i = w.geometry(*box())
    floor = w.mesh("floor", floor_a, floor_i, floor_m)
    wall = w.mesh("backdrop", floor_a, floor_i, wall_m)
    lamp = w.mesh("lamp", floor_a, floor_i, lamp_m)
    gold = w.mesh("gold ball", sphere_a, sphere_i, gold_m)
    glass = w.mesh("glass ball", sphere_a, sphere_i, glass_m)
    red = w.mesh("red box", box_a, box_i, red_m)

    s45 = math.sin(math.pi / 4)
    nodes = [
        w.node({"name": "floor", "mesh": floor}),
        # The backdrop: the floor quad stood up (turned 90 degrees about +x) at z = -2.
        w.node({"name": "backdrop", "mesh": wall, "translation": [0, 2.5, -2.0],
                "rotation": [s45, 0, 0, s45], "scale": [1, 1, 5 / 6]}),
        # The panel: the quad turned over to face down, small, high up.
        w.node({"name": "lamp", "mesh": lamp, "translation": [0, 3.2, 0.5],
                "rotation": [1, 0, 0, 0], "scale": [0.3, 1, 0.3]}),
        w.node({"name": "gold ball", "mesh": gold, "translation": [-1.0, 0.55, 0.2],
                "scale": [0.55, 0.55, 0.55]}),
        w.node({"name": "glass ball", "mesh": glass, "translation": [1.0, 0.45, 0.5],
                "scale": [0.45, 0.45, 0.45]}),
        w.node({"name": "red box", "mesh": red, "translation": [0.0, 0.35, -0.7],
                "rotation": [0, math.sin(math.pi / 12), 0, math.cos(math.pi / 12)],
                "scale": [0.7, 0.7, 0.7]}),
    ]
    eye, target = [0.0, 1.7, 4.6], [0.0, 0.55, 0.0]
    w.doc["cameras"] = [{"name": "front", "type": "perspective",
                         "perspective": {"yfov": 0.6, "aspectRatio": 1.6, "znear": 0.05}}]
    nodes.append(w.node({"name": "front camera", "camera": 0, "translation": eye,
                         "rotation": look_rotation(eye, target)}))
    spot_eye = [2.5, 4.0, 2.5]
    w.doc["extensionsUsed"] = ["KHR_lights_punctual", "KHR_materials_transmission",
                               "KHR_materials_ior", "KHR_materials_volume",
                               "KHR_materials_emissive_strength", "KHR_texture_transform"]
    # 20 W/sr at 683 lm/W.
    w.doc["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"name": "key", "type": "spot", "color": [1.0, 0.96, 0.9], "intensity": 20 * 683,
         "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.5}}]}}
    nodes.append(w.node({"name": "key light", "translation": spot_eye,
                         "rotation": look_rotation(spot_eye, [0, 0.3, 0]),
                         "extensions": {"KHR_lights_punctual": {"light": 0}}}))
    w.doc["scenes"] = [{"name": "product", "nodes": nodes}]
    w.doc["scene"] = 0

    while len(w.bin) % 4:
        w.bin.append(0)
    w.doc["buffers"] = [{"byteLength": len(w.bin)}]
    text = json.dumps(w.doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    glb = struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(text) + 8 + len(w.bin))
    glb += struct.pack("<I4s", len(text), b"JSON") + text
    glb += struct.pack("<I4s", len(w.bin), b"BIN\x00") + bytes(w.bin)
    Path(folder, "product.glb").write_bytes(glb)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "scenes/product")
