"""Build the shipped glTF scene ``shadowlab/scenes/gltf/blender_cube.glb`` with Blender.

Not an experiment (the Makefile's EXPERIMENTS list leaves it out): a script for Blender's own
Python, so that one glTF file in the lab comes from a real exporter rather than from the lab's
reader's author. Run from the repository root:

    blender -b --factory-startup --python experiments/make_gltf_scene.py

It builds Blender's default cube (2 m, at the origin) on a 12 m ground plane and a second,
smaller box, lit by a sun, a spot and a point light (Blender's 1000 W defaults, which the
exporter writes in candela: KHR_lights_punctual), seen by two perspective cameras, and exports
them with ``bpy.ops.export_scene.gltf`` (+Y up, the lab's axes). ``shadowlab/scenes/gltf_blender_cube.toml``
includes the file; docs/your-scenes.md#gltf-scenes walks through it.
"""
import math
import os

import bpy
from mathutils import Vector

OUT = os.path.join(os.getcwd(), "shadowlab", "scenes", "gltf", "blender_cube.glb")


def look_at(obj, target):
    """Turn ``obj`` (a camera or light: it looks down its local -Z, up +Y) towards ``target``."""
    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene

    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 0.0))
    bpy.context.object.name = "Cube"
    bpy.ops.mesh.primitive_plane_add(size=12.0, location=(0.0, 0.0, -1.0))
    bpy.context.object.name = "Ground"
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(2.2, -1.4, -0.25), rotation=(0.0, 0.0, math.radians(30)))
    bpy.context.object.name = "Crate"
    for name, rgb in (("Cube", (0.8, 0.3, 0.2)), ("Ground", (0.8, 0.8, 0.8)), ("Crate", (0.2, 0.4, 0.8))):
        mat = bpy.data.materials.new(name + "Material")
        mat.use_nodes = True
        mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*rgb, 1.0)
        bpy.data.objects[name].data.materials.append(mat)

    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0  # W/m²: the exporter writes lux
    sun.location = (4.0, -3.0, 6.0)
    look_at(sun, (0.0, 0.0, 0.0))
    spot = bpy.data.objects.new("Spot", bpy.data.lights.new("Spot", "SPOT"))
    spot.data.energy = 1000.0
    spot.data.spot_size = math.radians(60.0)
    spot.data.spot_blend = 0.3
    spot.location = (-3.0, -2.0, 5.0)
    look_at(spot, (0.0, 0.0, -1.0))
    point = bpy.data.objects.new("Point", bpy.data.lights.new("Point", "POINT"))
    point.data.energy = 1000.0
    point.location = (3.0, 3.0, 3.0)
    for obj in (sun, spot, point):
        scene.collection.objects.link(obj)

    main_cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    main_cam.location = (7.0, -6.5, 5.0)
    look_at(main_cam, (0.0, 0.0, -0.5))
    top_cam = bpy.data.objects.new("TopCamera", bpy.data.cameras.new("TopCamera"))
    top_cam.data.lens = 35.0
    top_cam.location = (0.5, -1.0, 12.0)
    look_at(top_cam, (0.0, 0.0, 0.0))
    for obj in (main_cam, top_cam):
        scene.collection.objects.link(obj)
    scene.camera = main_cam
    scene.render.resolution_x, scene.render.resolution_y = 640, 480

    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    bpy.ops.export_scene.gltf(filepath=OUT, export_format="GLB", export_lights=True, export_cameras=True,
                              export_yup=True, export_apply=True)
    print("wrote", OUT)


main()
