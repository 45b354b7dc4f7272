"""Read a Blender scene's visible Light objects into ``lights.Light`` (world space, Cycles units).

Point and spot lights keep their radius (soft shadows) but not Blender's "soft falloff"
near-field shaping: within a radius or two of the light RadTR uses the plain inverse square.
A light with a NaN, infinite or negative power is skipped with a warning naming it.
"""
from __future__ import annotations

import numpy as np

from ..lights import KINDS, Light
from .images import image_pixels


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


def world_radiance(bl_scene):
    """(radiance(dirs) -> (k, 3) or None, warnings) of the scene's World as a distant sky.

    Read: the Background node on the World Output's Surface, Color x Strength; a Color linked
    from an Environment Texture gives radiance by direction (equirectangular, sRGB images
    made linear). Anything else, or an image that cannot be loaded, falls back to the
    socket's own colour with a warning naming the world and node.
    """
    from ..lights import equirect_lookup

    world, warnings = bl_scene.world, []
    if world is None or world.node_tree is None:
        return None, warnings
    out = next((n for n in world.node_tree.nodes if n.type == "OUTPUT_WORLD" and n.is_active_output), None)
    link = out.inputs["Surface"].links[0] if out and out.inputs["Surface"].is_linked else None
    node = link.from_node if link else None
    if node is None or node.type != "BACKGROUND":
        if node is not None:
            warnings.append(f"world '{world.name}': node '{node.name}' is not a Background; the world gives no light")
        return None, warnings
    strength = float(node.inputs["Strength"].default_value)
    color = np.array(node.inputs["Color"].default_value[:3], float)
    if node.inputs["Strength"].is_linked:
        warnings.append(f"world '{world.name}': Strength of '{node.name}' is linked; using its value {strength:g}")
    if node.inputs["Color"].is_linked:
        src = node.inputs["Color"].links[0].from_node
        image = getattr(src, "image", None) if src.type == "TEX_ENVIRONMENT" else None
        pixels = image_pixels(image)
        if pixels is not None:
            lookup = equirect_lookup(pixels[::-1] * strength)            # row 0 at the top
            return lookup, warnings
        what = (f"image '{image.name}' could not be loaded" if image is not None and src.type == "TEX_ENVIRONMENT"
                else f"node '{src.name}' cannot be evaluated")
        warnings.append(f"world '{world.name}': {what}; using the Background colour instead")
    if not np.isfinite(strength) or strength * color.max() <= 0:
        return None, warnings
    radiance = color * strength
    return (lambda dirs: np.broadcast_to(radiance, (len(dirs), 3))), warnings

