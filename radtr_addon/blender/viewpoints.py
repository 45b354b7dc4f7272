"""Saved viewpoints in the .blend (``scene.radtr.views``: name, target, rotation, distance,
lens each) and what the viewer shows of a view: its eye, forward and right vectors.

A view is the 3D viewport's own state (``RegionView3D``: it orbits a target ``location`` at
``distance``, turned by ``rotation``); a camera made from it (``camera_from_view``) sees
what the viewport saw, so ``--camera NAME`` and Capture render a saved view.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .named import add_named


def _quat_matrix(q) -> np.ndarray:
    """3 x 3 rotation of the unit quaternion (w, x, y, z)."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def eye_axes(location, rotation, distance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(eye, forward, right) of a view orbiting ``location`` at ``distance``, turned by ``rotation``
    (w, x, y, z): a view looks along its -Z, its +X to the right."""
    R = _quat_matrix(rotation)
    return np.asarray(location, float) + distance * R[:, 2], -R[:, 2], R[:, 0]


def store_view(settings, rv3d, name: str, lens: float = 50.0):
    """A new saved view (unique name) holding the viewport state ``rv3d`` and its ``lens`` (mm)."""
    item = add_named(settings.views, name)
    item.location, item.rotation = tuple(rv3d.view_location), tuple(rv3d.view_rotation)
    item.distance, item.lens = float(rv3d.view_distance), lens
    return item


def recall_view(item, rv3d):
    """Put the viewport ``rv3d`` where the saved view ``item`` was."""
    rv3d.view_perspective = "PERSP"
    rv3d.view_location, rv3d.view_rotation = tuple(item.location), tuple(item.rotation)
    rv3d.view_distance = item.distance


class SavedView(NamedTuple):
    name: str
    location: tuple
    rotation: tuple
    distance: float
    lens: float


def saved_views(bl_scene) -> list[SavedView]:
    """The scene's saved views, also where the add-on is not registered (the command line
    reads the .blend's raw properties; unset fields have the properties' defaults)."""
    registered = getattr(bl_scene, "radtr", None)
    if registered is not None:
        raw = registered.views
    else:                         # Blender 5 keeps add-on properties apart from custom ones
        system = bl_scene.bl_system_properties_get() if hasattr(bl_scene, "bl_system_properties_get") else bl_scene
        raw = ((system or {}).get("radtr") or {}).get("views") or []
    out = []
    for v in raw:
        get = (lambda key, default, v=v: getattr(v, key)) if registered is not None else v.get
        out.append(SavedView(get("name", ""), tuple(get("location", (0.0, 0.0, 0.0))),
                             tuple(get("rotation", (1.0, 0.0, 0.0, 0.0))), float(get("distance", 10.0)),
                             float(get("lens", 50.0))))
    return out


def camera_from_view(bl_scene, item):
    """A temporary camera object at the saved view ``item`` (the caller removes it)."""
    import bpy

    eye, _, _ = eye_axes(item.location, item.rotation, item.distance)
    data = bpy.data.cameras.new(f"RadTR view {item.name}")
    data.lens, data.sensor_width, data.sensor_fit = item.lens, 36.0, "AUTO"
    cam = bpy.data.objects.new(f"RadTR view {item.name}", data)
    bl_scene.collection.objects.link(cam)
    cam.location = tuple(eye)
    cam.rotation_mode = "QUATERNION"
    cam.rotation_quaternion = tuple(item.rotation)
    return cam


def info_line(rv3d) -> str:
    """Eye, forward and right of the viewport ``rv3d``, for the panel."""
    axes = eye_axes(rv3d.view_location, rv3d.view_rotation, rv3d.view_distance)
    shown = ["(" + ", ".join(f"{x:.3g}" for x in v) + ")" for v in axes]
    return "eye {}  forward {}  right {}".format(*shown)
