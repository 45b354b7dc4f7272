"""The Cornell box, from the published Cornell measurements.

Geometry: http://www.graphics.cornell.edu/online/box/data.html (millimetres, y up, open at
z = 0), placed in Blender in metres with z up: (x, y, z)_Blender = (x, -z, y) / 1000.
The ceiling has a hole where the light sits (as in the real box), so the light's back side
faces nothing. RGB reflectances are the usual fits to the measured spectra; the light's
radiance (17, 12, 4) W/(m^2 sr) is the one PBRT and Tungsten scenes use, i.e. Blender
emission Strength 17 with Color (1, 12/17, 4/17).
The camera is the published one: (278, 273, -800) looking +z, 35 mm lens, 25 mm film.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np

_spec = importlib.util.spec_from_file_location("radtr_scene_common", Path(__file__).with_name("_common.py"))
common = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(common)

MATERIALS = {  # name: (RGB reflectance, emitted radiance)
    "white": ((0.725, 0.71, 0.68), (0.0, 0.0, 0.0)),
    "red": ((0.63, 0.065, 0.05), (0.0, 0.0, 0.0)),
    "green": ((0.14, 0.45, 0.091), (0.0, 0.0, 0.0)),
    "light": ((0.78, 0.78, 0.78), (17.0, 12.0, 4.0)),
}

_LIGHT = ((343.0, 548.8, 227.0), (343.0, 548.8, 332.0), (213.0, 548.8, 332.0), (213.0, 548.8, 227.0))
_Y = 548.8


def _ceiling():
    x0, x1, z0, z1 = 213.0, 343.0, 227.0, 332.0
    return [
        ((556.0, _Y, 0.0), (556.0, _Y, z0), (0.0, _Y, z0), (0.0, _Y, 0.0)),
        ((556.0, _Y, z1), (556.0, _Y, 559.2), (0.0, _Y, 559.2), (0.0, _Y, z1)),
        ((556.0, _Y, z0), (556.0, _Y, z1), (x1, _Y, z1), (x1, _Y, z0)),
        ((x0, _Y, z0), (x0, _Y, z1), (0.0, _Y, z1), (0.0, _Y, z0)),
    ]


#: name: (material, quads in Cornell millimetres, which way normals face)
SURFACES = {
    "floor": ("white", [((552.8, 0, 0), (0, 0, 0), (0, 0, 559.2), (549.6, 0, 559.2))], "in"),
    "ceiling": ("white", _ceiling(), "in"),
    "back_wall": ("white", [((549.6, 0, 559.2), (0, 0, 559.2), (0, 548.8, 559.2), (556, 548.8, 559.2))], "in"),
    "green_wall": ("green", [((0, 0, 559.2), (0, 0, 0), (0, 548.8, 0), (0, 548.8, 559.2))], "in"),
    "red_wall": ("red", [((552.8, 0, 0), (549.6, 0, 559.2), (556, 548.8, 559.2), (556, 548.8, 0))], "in"),
    "short_block": ("white", [
        ((130, 165, 65), (82, 165, 225), (240, 165, 272), (290, 165, 114)),
        ((290, 0, 114), (290, 165, 114), (240, 165, 272), (240, 0, 272)),
        ((130, 0, 65), (130, 165, 65), (290, 165, 114), (290, 0, 114)),
        ((82, 0, 225), (82, 165, 225), (130, 165, 65), (130, 0, 65)),
        ((240, 0, 272), (240, 165, 272), (82, 165, 225), (82, 0, 225))], "out"),
    "tall_block": ("white", [
        ((423, 330, 247), (265, 330, 296), (314, 330, 456), (472, 330, 406)),
        ((423, 0, 247), (423, 330, 247), (472, 330, 406), (472, 0, 406)),
        ((472, 0, 406), (472, 330, 406), (314, 330, 456), (314, 0, 456)),
        ((314, 0, 456), (314, 330, 456), (265, 330, 296), (265, 0, 296)),
        ((265, 0, 296), (265, 330, 296), (423, 330, 247), (423, 0, 247))], "out"),
    "light": ("light", [_LIGHT], "down"),
}

ROOM_CENTRE = np.array([278.0, 274.4, 279.6])


def to_blender(points) -> np.ndarray:
    """Cornell millimetres (y up) to Blender metres (z up)."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1) / 1000.0


def oriented_quads(name: str) -> np.ndarray:
    """(q, 4, 3) quads of surface ``name`` in Cornell mm, wound so normals face as intended."""
    _, quads, facing = SURFACES[name]
    quads = np.array(quads, dtype=np.float64)
    centre = quads.reshape(-1, 3).mean(axis=0)
    out = []
    for q in quads:
        normal = np.cross(q[1] - q[0], q[2] - q[0])
        c = q.mean(axis=0)
        want = {"in": ROOM_CENTRE - c, "out": c - centre, "down": np.array([0.0, -1.0, 0.0])}[facing]
        out.append(q if normal @ want > 0 else q[::-1])
    return np.array(out)


def build(bpy):
    """Add the Cornell box (objects, materials, camera) to the current scene; return the scene."""
    scene = bpy.context.scene
    mats = {}
    for name, (rho, radiance) in MATERIALS.items():
        strength = max(radiance)
        colour = [c / strength for c in radiance] if strength > 0 else (1.0, 1.0, 1.0)
        mats[name] = common.material(bpy, name, rho, strength, colour)
    for name, (mat, _, _) in SURFACES.items():
        quads = to_blender(oriented_quads(name))
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(quads.reshape(-1, 3).tolist(), [], np.arange(len(quads) * 4).reshape(-1, 4).tolist())
        mesh.materials.append(mats[mat])
        mesh.update()
        scene.collection.objects.link(bpy.data.objects.new(name, mesh))
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens, cam_data.sensor_width, cam_data.sensor_fit = 35.0, 25.0, "HORIZONTAL"
    cam = bpy.data.objects.new("camera", cam_data)
    cam.location = to_blender((278.0, 273.0, -800.0))
    cam.rotation_euler = (math.pi / 2, 0.0, math.pi)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x = scene.render.resolution_y = 512
    scene.view_settings.view_transform = "Standard"
    return scene
