#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Writes the seed corpus of fuzz_gltf (tests/fuzz/corpus/gltf/): a few tiny valid glTF 2.0 assets
that between them use every part of the reader (data: URIs and GLB BIN chunks, strided and
normalised attributes, strips and fans, node hierarchies with TRS and matrices, materials with
every texture slot, cameras and KHR_lights_punctual). External URIs are left out: the fuzz target
reads from memory, without a folder.

Usage: tests/fuzz/make_gltf_corpus.py [OUT_DIR]
"""
import base64
import json
import os
import struct
import zlib
import sys


class Bin:
    def __init__(self):
        self.data = bytearray()
        self.views = []

    def add(self, raw, stride=None):
        while len(self.data) % 4:
            self.data.append(0)
        view = {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw)}
        if stride:
            view["byteStride"] = stride
        self.data += raw
        self.views.append(view)
        return len(self.views) - 1


def floats(values):
    return struct.pack("<%df" % len(values), *values)


def as_gltf(doc, b):
    doc = dict(doc)
    uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(b.data)).decode()
    doc["buffers"] = [{"uri": uri, "byteLength": len(b.data)}]
    doc["bufferViews"] = b.views
    return json.dumps(doc, separators=(",", ":")).encode()


def as_glb(doc, b):
    doc = dict(doc)
    doc["buffers"] = [{"byteLength": len(b.data)}]
    doc["bufferViews"] = b.views
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    bn = bytes(b.data) + b"\0" * (-len(b.data) % 4)
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(bn), b"BIN\0") + bn
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


ASSET = {"version": "2.0", "generator": "make_gltf_corpus.py"}


def triangle():
    b = Bin()
    b.add(floats([0, 0, 0, 1, 0, 0, 0, 1, 0]))
    return {"asset": ASSET, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}]}, b


def png_rgba(width, height, rgba):
    """A real PNG (8-bit RGBA, no filter), so the decoder's path is in the corpus."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    rows = b"".join(b"\x00" + bytes(rgba[y * width * 4:(y + 1) * width * 4]) for y in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def textured_quad():
    b = Bin()
    b.add(floats([0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0]))
    b.add(floats([0, 0, 1, 0, 1, 1, 0, 1]))
    b.add(struct.pack("<6H", 0, 1, 2, 0, 2, 3))
    image = b.add(png_rgba(2, 2, [255, 0, 0, 255, 0, 0, 255, 0, 0, 255, 0, 255, 128, 128, 128, 128]))
    return {"asset": ASSET, "scenes": [{"nodes": [0]}], "nodes": [{"name": "quad", "mesh": 0}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"},
                          {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                          {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2,
                                        "material": 0}]}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "alphaMode": "MASK",
                           "alphaCutoff": 0.4, "doubleSided": True}],
            "textures": [{"source": 0, "sampler": 0}],
            "samplers": [{"magFilter": 9728, "minFilter": 9986, "wrapS": 33648, "wrapT": 33071}],
            "images": [{"bufferView": image, "mimeType": "image/png"}]}, b


def strips_and_nodes():
    b = Bin()
    b.add(floats([0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0]))
    b.add(bytes([0, 1, 2, 3, 4]))
    return {"asset": ASSET, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"name": "root", "translation": [1, 0, 0], "rotation": [0, 0.7071068, 0, 0.7071068],
                       "children": [1, 2]},
                      {"name": "strip", "mesh": 0, "scale": [2, 2, 2]},
                      {"name": "fan", "mesh": 1,
                       "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 3, 0, 1], "children": [3]},
                      {"name": "strip", "mesh": 0}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 5, "type": "VEC3"},
                          {"bufferView": 1, "componentType": 5121, "count": 5, "type": "SCALAR"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 5}]},
                       {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 6},
                                       {"attributes": {"POSITION": 0}, "mode": 1}]}]}, b


def interleaved():
    b = Bin()
    vertices = bytearray()
    for x, y in ((0, 0), (1, 0), (0, 1)):
        vertices += floats([x, y, 0, 0, 0, 1])
    b.add(bytes(vertices), stride=24)
    b.add(bytes([255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 128]))
    b.add(struct.pack("<6H", 0, 0, 65535, 0, 0, 65535))
    return {"asset": ASSET, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                          {"bufferView": 0, "byteOffset": 12, "componentType": 5126, "count": 3, "type": "VEC3"},
                          {"bufferView": 1, "componentType": 5121, "normalized": True, "count": 3, "type": "VEC4"},
                          {"bufferView": 2, "componentType": 5123, "normalized": True, "count": 3, "type": "VEC2"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2,
                                                       "TEXCOORD_1": 3}}]}]}, b


def lights_and_materials():
    doc, b = triangle()
    doc = dict(doc)
    doc["extensionsUsed"] = ["KHR_lights_punctual", "KHR_materials_emissive_strength"]
    doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1, "zfar": 50}},
                      {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0, "zfar": 5}}]
    doc["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "spot", "color": [1, 0.9, 0.8], "intensity": 20, "range": 10,
         "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.5}},
        {"type": "directional", "intensity": 2}]}}
    doc["nodes"] = [{"mesh": 0}, {"camera": 0}, {"extensions": {"KHR_lights_punctual": {"light": 0}}}]
    doc["scenes"] = [{"nodes": [0, 1, 2]}]
    doc["textures"] = [{"source": 0}]
    doc["images"] = [{"uri": "data:image/png;base64,iVBORw0KGgo="}]
    slot = {"index": 0, "texCoord": 1}
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [1, 0.5, 0.5, 1], "baseColorTexture": slot,
                                                  "metallicRoughnessTexture": slot},
                         "normalTexture": dict(slot, scale=0.5), "occlusionTexture": dict(slot, strength=0.8),
                         "emissiveTexture": slot, "emissiveFactor": [1, 1, 0],
                         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 5}}}]
    doc["meshes"] = [{"primitives": [{"attributes": {"POSITION": 0}, "material": 0}]}]
    return doc, b


def main(argv):
    out = argv[1] if len(argv) > 1 else os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "gltf")
    os.makedirs(out, exist_ok=True)
    files = {
        "triangle.gltf": as_gltf(*triangle()),
        "triangle.glb": as_glb(*triangle()),
        "textured_quad.glb": as_glb(*textured_quad()),
        "strips_and_nodes.gltf": as_gltf(*strips_and_nodes()),
        "interleaved.glb": as_glb(*interleaved()),
        "lights_and_materials.gltf": as_gltf(*lights_and_materials()),
    }
    for name, data in files.items():
        with open(os.path.join(out, name), "wb") as f:
            f.write(data)
    print("wrote %d files to %s" % (len(files), out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
