#!/usr/bin/env python3
"""Writes the text glTF seeds of fuzz/corpus/gltf/ (fuzz/make_seeds.sh runs it): a quad with
normals, texture coordinates, a material with every supported extension, a triangle fan, an
orthographic camera and spot and directional lights; the same with an external buffer that is
too short, and with a node cycle."""
import base64
import json
import struct
import sys
from pathlib import Path

out = Path(sys.argv[1])
pos = struct.pack('<12f', 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0)
nor = struct.pack('<12f', *([0, 0, 1] * 4))
uv = struct.pack('<8f', 0, 1, 1, 1, 1, 0, 0, 0)
idx = struct.pack('<6H', 0, 1, 2, 0, 2, 3)
buf = pos + nor + uv + idx
uri = 'data:application/octet-stream;base64,' + base64.b64encode(buf).decode()
doc = {
    "asset": {"version": "2.0"},
    "buffers": [{"uri": uri, "byteLength": len(buf)}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                    {"buffer": 0, "byteOffset": 48, "byteLength": 48},
                    {"buffer": 0, "byteOffset": 96, "byteLength": 32},
                    {"buffer": 0, "byteOffset": 128, "byteLength": 12}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                  {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
                  {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
                  {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    "materials": [{"name": "m",
                   "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.2, 0.2, 1],
                                            "metallicFactor": 0.5, "roughnessFactor": 0.3},
                   "emissiveFactor": [0.1, 0.1, 0.1], "alphaMode": "MASK", "doubleSided": True,
                   "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2},
                                  "KHR_materials_ior": {"ior": 1.4},
                                  "KHR_materials_transmission": {"transmissionFactor": 0.5},
                                  "KHR_materials_volume": {"thicknessFactor": 0.1,
                                                           "attenuationColor": [0.9, 0.5, 0.5],
                                                           "attenuationDistance": 2}}}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
                                "indices": 3, "material": 0}]},
               {"primitives": [{"attributes": {"POSITION": 0}, "mode": 6}]}],
    "cameras": [{"type": "orthographic",
                 "orthographic": {"xmag": 2, "ymag": 1, "znear": 0.1, "zfar": 10}}],
    "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength",
                       "KHR_materials_ior", "KHR_materials_transmission",
                       "KHR_materials_volume"],
    "extensions": {"KHR_lights_punctual": {"lights": [
        {"type": "spot", "intensity": 100, "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.4}},
        {"type": "directional", "color": [1, 0.9, 0.8], "intensity": 3}]}},
    "nodes": [{"mesh": 0, "children": [1, 2]},
              {"mesh": 1, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -1, 1]},
              {"camera": 0, "translation": [0, 0, 5]},
              {"rotation": [0.3826834, 0, 0, 0.9238795],
               "extensions": {"KHR_lights_punctual": {"light": 0}}},
              {"extensions": {"KHR_lights_punctual": {"light": 1}}}],
    "scenes": [{"nodes": [0, 3, 4]}],
    "scene": 0,
}
(out / "quad.gltf").write_text(json.dumps(doc))
short = json.loads(json.dumps(doc))
short["buffers"][0] = {"uri": "f.bin", "byteLength": 10}
(out / "external-buffer.gltf").write_text(json.dumps(short))
cycle = json.loads(json.dumps(doc))
cycle["nodes"][1]["children"] = [0]
(out / "cycle.gltf").write_text(json.dumps(cycle))
