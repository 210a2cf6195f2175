"""Write ``fixture.gltf`` beside this script: a small hand-made glTF 2.0 file for
tests/scene/test_gltf.py (run it again after changing it: ``python tests/scene/gltf/make_fixture.py``).

It exercises what the reader must get right: a node hierarchy (a rotated, translated root with
children), a ``matrix`` node beside TRS nodes, a mesh used by two nodes of the same name, a mesh
with a triangle primitive and a points primitive, a spot with inner and outer cones, a ranged
point light, a light of an unknown type, two perspective cameras (one under a rotated parent)
and an orthographic one, an unsupported extension, a skin and a morph target. Every buffer is
inline (a base64 data: URI), so the fixture is one file.
"""
import base64
import json
import math
import struct
from pathlib import Path

# a unit cube centred at the origin: 8 corners, 12 triangles, CCW outward
CUBE_V = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
CUBE_F = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
          (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
FLOOR_V = [(-3.0, 0.0, -3.0), (-3.0, 0.0, 3.0), (3.0, 0.0, 3.0), (3.0, 0.0, -3.0)]
FLOOR_F = [(0, 1, 2), (0, 2, 3)]


def main():
    blob = bytearray()
    views, accessors = [], []

    def add(data: bytes, target=None):
        blob.extend(b"\0" * (-len(blob) % 4))
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data), **({"target": target} if target else {})})
        blob.extend(data)
        return len(views) - 1

    def positions(vs):
        lo = [min(v[i] for v in vs) for i in range(3)]
        hi = [max(v[i] for v in vs) for i in range(3)]
        view = add(b"".join(struct.pack("<3f", *v) for v in vs), 34962)
        accessors.append({"bufferView": view, "componentType": 5126, "count": len(vs), "type": "VEC3", "min": lo, "max": hi})
        return len(accessors) - 1

    def indices(fs):
        view = add(b"".join(struct.pack("<3H", *f) for f in fs), 34963)
        accessors.append({"bufferView": view, "componentType": 5123, "count": 3 * len(fs), "type": "SCALAR"})
        return len(accessors) - 1

    cube_pos, cube_idx = positions(CUBE_V), indices(CUBE_F)
    cube_morph = positions([(0.0, 0.1, 0.0)] * len(CUBE_V))
    floor_pos, floor_idx = positions(FLOOR_V), indices(FLOOR_F)
    s = math.sqrt(0.5)
    doc = {
        "asset": {"version": "2.0", "generator": "shadowlab tests/scene/gltf/make_fixture.py"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"name": "main", "nodes": [0, 3, 6, 8]}],
        "nodes": [
            # 0: root, +1 in y, turned 90 degrees about y (x -> -z, z -> x)
            {"name": "Root", "translation": [0.0, 1.0, 0.0], "rotation": [0.0, s, 0.0, s], "children": [1, 2, 4, 5]},
            # 1: a box by matrix (column-major): scale 0.5, then +2 in x
            {"name": "Box", "mesh": 0, "skin": 0,
             "matrix": [0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 2.0, 0.0, 0.0, 1.0]},
            # 2: the same mesh by TRS, and the same node name
            {"name": "Box", "mesh": 0, "translation": [-2.0, 0.0, 0.0], "scale": [1.0, 2.0, 1.0]},
            # 3: the floor: a triangle primitive and a points primitive
            {"name": "Floor", "mesh": 1},
            # 4: a spot 3 up from the root, pointing down (-Z turned to -Y by -90 degrees about x)
            {"name": "SpotNode", "translation": [0.0, 3.0, 0.0], "rotation": [-s, 0.0, 0.0, s],
             "extensions": {"KHR_lights_punctual": {"light": 0}}},
            # 5: a ranged point light
            {"name": "PointNode", "translation": [1.0, 2.0, 0.0], "extensions": {"KHR_lights_punctual": {"light": 1}}},
            # 6: camera A at (0, 2, 8) looking down -z; its child 7 carries an unknown light type
            {"name": "CamA", "camera": 0, "translation": [0.0, 2.0, 8.0], "children": [7]},
            {"name": "AreaNode", "extensions": {"KHR_lights_punctual": {"light": 2}}},
            # 8: a parent turned 90 degrees about y, its child camera B 8 along the parent's z;
            # 9: an orthographic camera
            {"name": "CamParent", "rotation": [0.0, s, 0.0, s], "children": [9, 10]},
            {"name": "CamBNode", "camera": 1, "translation": [0.0, 2.0, 8.0]},
            {"name": "OrthoNode", "camera": 2, "translation": [0.0, 10.0, 0.0]},
        ],
        "meshes": [
            {"name": "cube", "primitives": [{"attributes": {"POSITION": cube_pos}, "indices": cube_idx, "material": 0,
                                             "targets": [{"POSITION": cube_morph}]}], "weights": [0.0]},
            {"name": "floor", "primitives": [{"attributes": {"POSITION": floor_pos}, "indices": floor_idx, "material": 1},
                                             {"attributes": {"POSITION": floor_pos}, "mode": 0}]},
        ],
        "materials": [
            {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.2, 0.1, 1.0]},
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}}},
            {"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0]}},
        ],
        "skins": [{"joints": [0]}],
        "cameras": [
            {"name": "A", "type": "perspective", "perspective": {"yfov": math.radians(50.0), "znear": 0.1, "zfar": 100.0}},
            {"name": "B", "type": "perspective", "perspective": {"yfov": math.radians(40.0), "znear": 0.5}},
            {"name": "Top", "type": "orthographic", "orthographic": {"xmag": 4.0, "ymag": 3.0, "znear": 0.1, "zfar": 50.0}},
        ],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "Spot", "type": "spot", "color": [1.0, 0.9, 0.8], "intensity": 400.0,
             "spot": {"innerConeAngle": math.radians(20.0), "outerConeAngle": math.radians(35.0)}},
            {"name": "Lamp", "type": "point", "intensity": 50.0, "range": 12.0},
            {"name": "Panel", "type": "area", "intensity": 5.0},
        ]}},
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()}],
        "bufferViews": views,
        "accessors": accessors,
    }
    out = Path(__file__).with_name("fixture.gltf")
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print("wrote", out)


if __name__ == "__main__":
    main()
