"""Reflectance and emission of a Blender material, as RadTR reads them.

Emission units: Blender's emission Strength S with Color C makes a surface render with
radiance L = S C (a strength of 1 shows the colour as is). A diffuse emitter of radiance L
has exitance pi L, so RadTR's emission is E = pi S C in W/m^2 per channel; radiosity B
converts back to the radiance Cycles shows as B / pi.

Read, in order: the node linked to the active Material Output's Surface, when it is a
Principled BSDF (Base Color; Emission Color x Emission Strength), a Diffuse BSDF (Color) or
an Emission shader (Color x Strength, reflectance 0). A linked socket or another shader
falls back to the material's viewport colour with a warning naming material and node.

Sides: an emitting material emits from both sides, as Cycles renders a mesh light, unless
its Backface Culling setting is on; then only from the front (the side the normal faces).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Reflectance of faces without a material (what Blender renders them with).
DEFAULT_REFLECTANCE = (0.8, 0.8, 0.8)


@dataclass
class SurfaceProps:
    rho: np.ndarray        # (3,); for a texture, its mean
    emission: np.ndarray   # (3,) W/m^2
    warnings: list[str]
    texture: np.ndarray | None = None   # (h, w, 3) linear base colour image (``textures``)
    two_sided: bool = True              # emits from its back too (as Cycles renders a mesh light)
    attribute: str | None = None        # colour attribute name ("" = the mesh's active one)


def _rgb(socket) -> np.ndarray:
    return np.array(socket.default_value[:3], dtype=np.float64)


def _value(node, name):
    sock = node.inputs.get(name)
    return sock, (sock is not None and sock.is_linked)


def read_material(mat) -> SurfaceProps:
    """SurfaceProps of material ``mat`` (None: Blender's default grey, no emission)."""
    if mat is None:
        return SurfaceProps(np.array(DEFAULT_REFLECTANCE), np.zeros(3), [])
    warnings: list[str] = []
    fallback = np.array(mat.diffuse_color[:3], dtype=np.float64)
    node = _surface_node(mat)
    if node is None:
        return SurfaceProps(fallback, np.zeros(3), warnings)
    colour_input = {"BSDF_PRINCIPLED": "Base Color", "BSDF_DIFFUSE": "Color"}.get(node.type)
    varying = _varying_colour(mat, node, colour_input, warnings) if colour_input else None
    if varying is not None:
        texture, attribute, rho = varying
        props = _read_constant(mat, node, rho, warnings, skip=colour_input)
        props.texture, props.attribute = texture, attribute
    else:
        props = _read_constant(mat, node, fallback, warnings)
    props.two_sided = not mat.use_backface_culling
    return props


def _read_constant(mat, node, fallback, warnings, skip=None) -> SurfaceProps:
    """Reflectance and emission of the surface shader ``node`` (``skip``: a colour input read elsewhere)."""
    rho, emission = fallback, np.zeros(3)
    if node.type == "BSDF_PRINCIPLED":
        if skip != "Base Color":
            rho = _socket_rgb(mat, node, "Base Color", fallback, warnings)
        color = _socket_rgb(mat, node, "Emission Color", np.zeros(3), warnings)
        strength = _socket_float(mat, node, "Emission Strength", 0.0, warnings)
        emission = np.pi * strength * color
    elif node.type == "BSDF_DIFFUSE":
        if skip != "Color":
            rho = _socket_rgb(mat, node, "Color", fallback, warnings)
    elif node.type == "EMISSION":
        rho = np.zeros(3)
        color = _socket_rgb(mat, node, "Color", np.ones(3), warnings)
        emission = np.pi * _socket_float(mat, node, "Strength", 1.0, warnings) * color
    else:
        warnings.append(f"material '{mat.name}': shader node '{node.name}' ({node.type}) is not "
                        f"read by RadTR; using its viewport colour {tuple(np.round(fallback, 3))}")
    return SurfaceProps(rho, emission, warnings)


def _varying_colour(mat, node, name, warnings):
    """(texture, attribute, mean colour) when ``name`` is fed by an Image Texture or a Color
    Attribute node; None otherwise (the caller reads the socket as a constant)."""
    from .images import image_pixels

    sock = node.inputs.get(name)
    if sock is None or not sock.is_linked:
        return None
    src = sock.links[0].from_node
    if src.type == "TEX_IMAGE":
        pixels = image_pixels(src.image)
        if pixels is None:
            what = f"image '{src.image.name}'" if src.image else "no image"
            warnings.append(f"material '{mat.name}': Image Texture '{src.name}' has {what} that could not be "
                            f"loaded; using the '{name}' value instead")
            return None
        return pixels, None, pixels.reshape(-1, 3).mean(axis=0)
    if src.type == "VERTEX_COLOR":
        return None, src.layer_name, np.array(sock.default_value[:3], float)
    return None


def _surface_node(mat):
    import bpy

    if mat.node_tree is None or (bpy.app.version < (5, 0, 0) and not mat.use_nodes):
        return None
    outputs = [n for n in mat.node_tree.nodes if n.type == "OUTPUT_MATERIAL"]
    active = [n for n in outputs if n.is_active_output] or outputs
    if not active or not active[0].inputs["Surface"].is_linked:
        return None
    return active[0].inputs["Surface"].links[0].from_node


def _socket_rgb(mat, node, name, default, warnings):
    sock, linked = _value(node, name)
    if sock is None:
        return default
    if linked:
        warnings.append(f"material '{mat.name}': '{node.name}' input '{name}' is driven by a node "
                        f"RadTR does not evaluate; using its unlinked value")
    return _rgb(sock)


def _socket_float(mat, node, name, default, warnings):
    sock, linked = _value(node, name)
    if sock is None:
        return default
    if linked:
        warnings.append(f"material '{mat.name}': '{node.name}' input '{name}' is driven by a node "
                        f"RadTR does not evaluate; using its unlinked value")
    return float(sock.default_value)
