"""Write ``blender_cube_twin/`` beside this script: the shipped scene ``gltf_blender_cube`` (which
includes Blender's glb) written as a plain TOML scene — each object an OBJ file of its welded
world-space vertices in repr() floats, lights and camera as the glTF reader mapped them — for the
test that both load to identical arrays and give identical metrics (tests/scene/test_gltf.py).
Run from the repository root after remaking the glb: ``python tests/scene/gltf/make_toml_twin.py``.
"""
from pathlib import Path

import numpy as np

from shadowlab.scene import load_scene

KEYS = {"point": ("position",), "directional": ("direction",), "spot": ("position", "direction", "alpha", "beta")}


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return repr(float(v))


def main():
    scene = load_scene("gltf_blender_cube")
    out = Path(__file__).with_name("blender_cube_twin")
    out.mkdir(exist_ok=True)
    cam = scene.camera
    lines = ["# The shipped scene gltf_blender_cube written as plain TOML by tests/scene/gltf/make_toml_twin.py:",
             "# the same arrays, lights and camera, no glTF (tests/scene/test_gltf.py).",
             'name = "gltf_blender_cube"', 'family = "general"', "", "[camera]"]
    lines += [f"{k} = {toml_value(getattr(cam, k))}" for k in ("eye", "target", "up", "fov_y", "near", "far")]
    for light in scene.lights:
        d = light.describe()
        lines += ["", "[[lights]]"] + [f"{k} = {toml_value(v)}" for k, v in d.items()]
    for obj in scene.objects:
        mesh = out / f"{obj.name}.obj"
        mesh.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in obj.vertices.tolist())
                        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in obj.faces.tolist()))
        lines += ["", "[[objects]]", f'name = "{obj.name}"', f'mesh = "{mesh.name}"',
                  "[objects.material]", f"diffuse = {toml_value(obj.material.diffuse)}"]
    (out / "scene.toml").write_text("\n".join(lines) + "\n")
    print("wrote", out)


if __name__ == "__main__":
    main()
