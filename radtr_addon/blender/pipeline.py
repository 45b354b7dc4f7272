"""One solve of a Blender scene: read it into the engine's ``SceneInput``, solve, write back.

``SolveJob`` is the engine's ``Solve`` (``radtr_addon.pipeline``) with the reading at its
start (meshes, materials, Light objects, the World) and the writing at its end (``finish``),
so the operators, the CLI and the benches share one pipeline. Until ``finish`` nothing in
the file changes, so dropping the job is a clean cancel.
"""
from __future__ import annotations

import time

from ..pipeline import Solve, Stats
from ..settings import Settings
from .extract import extract, source_objects
from .lights import scene_lights, world_radiance
from .write import check_replaceable, write_results


class SolveJob(Solve):
    """Read the Blender scene, then prepare the solve; shoot with ``advance``, write with ``finish``."""

    def __init__(self, bl_scene, depsgraph, view_layer, settings: Settings, log=print):
        self.bl_scene, self.view_layer = bl_scene, view_layer
        settings.validate()
        t0 = time.perf_counter()
        objects = source_objects(bl_scene, view_layer)
        if settings.mode == "REPLACE":
            check_replaceable(objects)
        self.extraction = extraction = extract(depsgraph, objects, settings.max_reflectance)
        extraction.lights, warnings = scene_lights(bl_scene, view_layer)
        extraction.world, sky_warnings = world_radiance(bl_scene)
        extraction.warnings += warnings + sky_warnings
        super().__init__(extraction, settings, log, Stats(seconds={"extract": time.perf_counter() - t0}))
        self.objects = []                       # the result objects, once written

    def finish(self) -> list:
        """Write the result into the file; returns the result objects."""
        self._conclude()
        with self._stage("write"):
            self.objects = write_results(self.bl_scene, self.extraction, self.leaves, self.B,
                                         self.settings.exposure, self.settings.mode, self.vertices)
        if self.settings.vertex_gather and self.settings.solver != "hierarchical":   # its gather: a stage of its own
            self.stats.seconds["vertex_gather"] = self.vertices.seconds
            self.stats.seconds["write"] -= self.vertices.seconds
        self.log(f"RadTR: {self.summary()}")
        return self.objects

    @property
    def instances(self) -> int:
        """How many of the meshes solved are instances."""
        return sum(1 for src in self.extraction.objects if src.instance)


def solve(context, settings: Settings, log=print, progress=None) -> SolveJob:
    """Solve the context's scene to completion and write the result (batch use)."""
    job = SolveJob(context.scene, context.evaluated_depsgraph_get(), context.view_layer, settings, log)
    job.run(progress)
    job.finish()
    return job
