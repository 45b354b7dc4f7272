"""Building blocks the bundled scenes share: materials, meshes, sun, sky and camera.

Scenes are loaded by path (``radtr_addon.blender.scenes.load_bundled``), so each loads this file the
same way, beside itself (``load``).
"""
from __future__ import annotations

import math

import numpy as np


def material(bpy, name, rho, strength=0.0, colour=(1.0, 1.0, 1.0)):
    """A rough, non-specular Principled material of reflectance ``rho``, emitting radiance
    ``strength`` x ``colour`` when ``strength`` > 0."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*rho, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    if strength > 0:
        bsdf.inputs["Emission Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    mat.diffuse_color = (*rho, 1.0)
    return mat


def look_rotation(direction):
    """Euler rotation that points an object's -Z along ``direction`` with +Y up."""
    from mathutils import Vector

    return Vector(tuple(direction)).to_track_quat("-Z", "Y").to_euler()


def add_sun(bpy, scene, strength, direction, location):
    """A sun of ``strength`` W/m^2, 0.5 degrees wide, shining along ``direction``."""
    data = bpy.data.lights.new("Sun", type="SUN")
    data.energy, data.angle = strength, math.radians(0.5)
    data.color = (1.0, 0.95, 0.88)
    sun = bpy.data.objects.new("Sun", data)
    sun.location = location
    sun.rotation_euler = look_rotation(direction)
    scene.collection.objects.link(sun)
    return sun


def add_sky(bpy, scene, colour):
    """A World named "Sky" of uniform background ``colour`` (RGB)."""
    world = bpy.data.worlds.new("Sky")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    background = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    background.inputs["Color"].default_value = (*colour, 1.0)
    background.inputs["Strength"].default_value = 1.0
    scene.world = world
    return world


def add_camera(bpy, scene, location, target, resolution, clip_end=None):
    """An 18 mm camera at ``location`` looking at ``target``, made the scene's camera."""
    data = bpy.data.cameras.new("Camera")
    data.lens, data.sensor_width, data.sensor_fit = 18.0, 36.0, "HORIZONTAL"
    if clip_end is not None:
        data.clip_end = clip_end
    cam = bpy.data.objects.new("Camera", data)
    location, target = np.asarray(location, float), np.asarray(target, float)
    cam.location = location
    cam.rotation_euler = look_rotation(target - location)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.view_settings.view_transform = "Standard"
    return cam
