"""Read a Blender scene's visible Light objects into ``lights.Light`` (world space, Cycles units).

Point and spot lights keep their radius (soft shadows) but not Blender's "soft falloff"
near-field shaping: within a radius or two of the light RadTR uses the plain inverse square.
A light with a NaN, infinite or negative power is skipped with a warning naming it.
"""
from __future__ import annotations

import numpy as np

from ..lights import KINDS, Light


def scene_lights(bl_scene, view_layer) -> tuple[list[Light], list[str]]:
    lights, warnings = [], []
    for obj in bl_scene.objects:
        if obj.type != "LIGHT" or not obj.visible_get(view_layer=view_layer):
            continue
        d = obj.data
        power = float(d.energy)
        if d.type not in KINDS:
            warnings.append(f"light '{obj.name}': type {d.type} is not supported; skipped")
            continue
        if not np.isfinite(power) or power < 0:
            warnings.append(f"light '{obj.name}': power {power} is not a finite, non-negative number; skipped")
            continue
        light = Light(obj.name, d.type, np.array(d.color[:3], float), power, np.array(obj.matrix_world))
        if d.type in ("POINT", "SPOT"):
            light.radius = float(d.shadow_soft_size)
        if d.type == "SPOT":
            light.spot_size, light.spot_blend = float(d.spot_size), float(d.spot_blend)
        if d.type == "SUN":
            light.radius = float(d.angle)
        if d.type == "AREA":
            light.shape, light.size_x, light.size_y = d.shape, float(d.size), float(d.size_y)
        lights.append(light)
    return lights, warnings
