"""The flashlight in Blender: result meshes rewritten in place, and the event handling.

``LiveMeshes`` writes a B into the result meshes' ``radtr_patch`` and ``radtr_radiosity``
attributes with ``foreach_set`` (no new datablocks), and can snapshot and restore them byte
for byte. ``FlashlightSession`` holds what the modal operator does with each event, free of
windows, so it runs headless from synthetic events too; ``render_poses`` is the batch use.
"""
from __future__ import annotations

import time
from collections import deque
from dataclasses import replace

import numpy as np

from ..lowrank.backends import DEFAULT_BACKEND
from ..lowrank.flashlight import Spot
from ..reconstruct import mesh_part, vertex_weights


class LiveMeshes:
    """The result meshes of a solve (``SolveJob.objects``), written every frame.

    Each mesh's vertex means are one sparse product (float32) and its colour buffers are
    kept between frames, so a frame is two products and two ``foreach_set`` a mesh."""

    def __init__(self, objects, leaves):
        self.leaves = leaves
        self.parts = []
        for obj in objects:
            mesh = obj.data
            ids = np.empty(len(mesh.polygons), dtype=np.int32)
            mesh.attributes["radtr_patch_index"].data.foreach_get("value", ids)
            part = mesh_part(leaves, ids.astype(np.int64))
            weights = vertex_weights(part.local, len(part.vertex_ids), leaves.areas[part.patches])
            buffers = (np.ones((len(part.patches), 4), dtype=np.float32),
                       np.ones((len(part.vertex_ids), 4), dtype=np.float32))
            self.parts.append((mesh, part, weights.astype(np.float32).tocsr(), buffers))

    def _attrs(self, mesh):
        return mesh.attributes["radtr_patch"], mesh.color_attributes["radtr_radiosity"]

    def snapshot(self) -> list:
        out = []
        for mesh, *_ in self.parts:
            pair = []
            for attr in self._attrs(mesh):
                buf = np.empty(len(attr.data) * 4, dtype=np.float32)
                attr.data.foreach_get("color", buf)
                pair.append(buf)
            out.append(pair)
        return out

    def restore(self, snapshot: list):
        for (mesh, *_), pair in zip(self.parts, snapshot):
            for attr, buf in zip(self._attrs(mesh), pair):
                attr.data.foreach_set("color", buf)
            mesh.update()

    def write(self, B: np.ndarray):
        """Patch colours and their area means at the vertices (as ``VertexRadiosity`` without
        gather) into every mesh."""
        B = np.asarray(B, dtype=np.float32)
        for mesh, part, weights, (patch_rgba, point_rgba) in self.parts:
            patch_rgba[:, :3] = B[part.patches]
            point_rgba[:, :3] = weights @ patch_rgba[:, :3]
            for attr, rgba in zip(self._attrs(mesh), (patch_rgba, point_rgba)):
                attr.data.foreach_set("color", rgba.ravel())
            mesh.update()


class FlashlightSession:
    """What the flashlight does with each event. ``handle`` returns the modal result:
    mouse aims (``ray`` = (origin, direction)), +/- size, wheel intensity, C colour/mono,
    P pins a copy of the spot where it is (pinned spots go on lighting), left click keeps the
    light, Esc or right click restores the colours as they were."""

    GROW = 1.2

    def __init__(self, flashlight, meshes: LiveMeshes, spot: Spot):
        self.flashlight, self.meshes, self.spot = flashlight, meshes, spot
        self.pinned: list[Spot] = []
        self.saved = meshes.snapshot()
        self.stages: dict[str, float] = {}
        self._frames: deque = deque(maxlen=30)

    @property
    def updates_per_second(self) -> float:
        if len(self._frames) < 2:
            return 0.0
        return (len(self._frames) - 1) / max(self._frames[-1] - self._frames[0], 1e-9)

    @property
    def header(self) -> str:
        ms = ", ".join(f"{k} {v * 1e3:.1f} ms" for k, v in self.stages.items())
        return (f"RadTR flashlight: {self.updates_per_second:.0f} updates/s ({ms}); "
                f"size {np.degrees(self.spot.angle):.0f} deg (+/-), intensity {self.spot.intensity:.3g} (wheel), "
                f"{'mono' if self.flashlight.mono else 'colour'} (C), {len(self.pinned)} pinned (P); "
                f"click keeps, Esc restores")

    def update(self):
        B, stages = self.flashlight.frame([*self.pinned, self.spot])
        t0 = time.perf_counter()
        self.meshes.write(B)
        self.stages = {**stages, "write": time.perf_counter() - t0}
        self._frames.append(time.perf_counter())

    def handle(self, event_type: str, value: str = "PRESS", ray=None) -> set:
        if event_type == "MOUSEMOVE" and ray is not None:
            self.spot.position, self.spot.direction = np.asarray(ray[0], float), np.asarray(ray[1], float)
        elif value != "PRESS" and event_type not in ("WHEELUPMOUSE", "WHEELDOWNMOUSE"):
            return {"RUNNING_MODAL"}
        elif event_type in ("NUMPAD_PLUS", "PLUS", "EQUAL"):
            self.spot.angle = min(self.spot.angle * self.GROW, np.radians(89.0))
        elif event_type in ("NUMPAD_MINUS", "MINUS"):
            self.spot.angle = max(self.spot.angle / self.GROW, np.radians(0.5))
        elif event_type == "WHEELUPMOUSE":
            self.spot.intensity *= 1.25
        elif event_type == "WHEELDOWNMOUSE":
            self.spot.intensity /= 1.25
        elif event_type == "C":
            self.flashlight.set_mono(not self.flashlight.mono)
        elif event_type == "P":
            self.pinned.append(replace(self.spot, position=self.spot.position.copy(),
                                       direction=self.spot.direction.copy()))
        elif event_type == "LEFTMOUSE":
            return {"FINISHED"}
        elif event_type in ("ESC", "RIGHTMOUSE"):
            self.meshes.restore(self.saved)
            return {"CANCELLED"}
        else:
            return {"PASS_THROUGH"}
        try:
            self.update()
        except Exception:                   # any failure of a frame: the colours go back first
            self.meshes.restore(self.saved)
            raise
        return {"RUNNING_MODAL"}


def default_spot(scene, position, direction) -> Spot:
    """A spot whose light on the scene is of the order of the scene's own emitters."""
    power = float(scene.emitted_power().max())
    return Spot(np.asarray(position, float), np.asarray(direction, float), intensity=max(power, 1e-9) / np.pi)


def render_poses(bl_scene, flashlight, meshes: LiveMeshes, spots, out_dir) -> list:
    """Batch use: one PNG per spot (``flashlight_000.png`` ...); the colours are restored after."""
    from pathlib import Path

    from .render import render_png

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    saved = meshes.snapshot()
    paths = []
    try:
        for k, spot in enumerate(spots):
            B, _ = flashlight.frame(spot)
            meshes.write(B)
            paths.append(out_dir / f"flashlight_{k:03d}.png")
            render_png(bl_scene, str(paths[-1].resolve()))
    finally:
        meshes.restore(saved)
    return paths


def cache_folder():
    """Where low-rank factors are kept: the extension's user folder, else Blender's temp folder.
    The extension's package is the one above ``radtr_addon`` ("bl_ext.<repository>.radtr"
    when installed), not the first part of this one's name ("bl_ext")."""
    from pathlib import Path

    import bpy

    extension = __package__.rpartition(".radtr_addon")[0]
    try:
        return Path(bpy.utils.extension_path_user(extension, path="lowrank", create=True))
    except (ValueError, KeyError, AttributeError):     # not running as an installed extension
        return Path(bpy.app.tempdir or "/tmp") / "radtr_lowrank"


def flashlight_for(job, level: int, backend: str = DEFAULT_BACKEND, folder=None, refine_to: int = 0, user: str = ""):
    """A Flashlight over a finished SolveJob: low-rank factors of ``level``, refined to
    ``refine_to`` clusters where the light is when that is more (cached), and the meshes to
    write to. Returns (flashlight, meshes, warnings, read_from_cache)."""
    from ..errors import SceneError, SettingsError
    from ..lowrank.cache import cached_build
    from ..lowrank.flashlight import Flashlight, ShadowGroups

    if not job.objects:
        raise SceneError("solve the scene first: the flashlight relights its result meshes")
    if job.hierarchy is None:
        raise SceneError("the flashlight's low-rank factors need the uniform patch hierarchy: "
                         "solve with a solver other than Hierarchical first")
    if not 0 <= level <= job.hierarchy.levels:
        raise SettingsError(f"low-rank level {level} is not a level of the hierarchy: 0..{job.hierarchy.levels}; "
                            f"lower the level or solve with more Levels")
    warnings: list[str] = []
    lowrank, hit = cached_build(job.hierarchy, job.rows, level, folder or cache_folder(),
                                ff_label=job.rows.settings.label(), refine_to=refine_to, warnings=warnings)
    light = Flashlight(job.leaves, lowrank, backend, user=user, warn=warnings.append,
                       groups=ShadowGroups.from_hierarchy(job.hierarchy))
    return light, LiveMeshes(job.objects, job.leaves), warnings, hit
