"""Operators, one a module (thin: settings in, one engine call, report); ``session`` holds what they share."""
import bpy

from .capture import RADTR_OT_capture
from .clear import RADTR_OT_clear
from .export import RADTR_OT_export
from .export_gltf import RADTR_OT_export_gltf
from .flashlight import RADTR_OT_flashlight
from .load_vector import RADTR_OT_load_vector
from .patch_view import RADTR_OT_patch_view
from .pick_view import RADTR_OT_pick_view
from .resume import RADTR_OT_resume
from .scenario_add import RADTR_OT_scenario_add
from .scenario_remove import RADTR_OT_scenario_remove
from .sequence import RADTR_OT_sequence
from .sky_factors import RADTR_OT_sky_factors
from .solve import RADTR_OT_solve
from .subdivide import RADTR_OT_subdivide
from .toggle_emission import RADTR_OT_toggle_emission
from .view_from_patch import RADTR_OT_view_from_patch
from .view_recall import RADTR_OT_view_recall
from .view_remove import RADTR_OT_view_remove
from .view_store import RADTR_OT_view_store
from .watch import RADTR_OT_watch

CLASSES = (RADTR_OT_subdivide, RADTR_OT_solve, RADTR_OT_resume, RADTR_OT_flashlight, RADTR_OT_scenario_add,
           RADTR_OT_scenario_remove, RADTR_OT_patch_view, RADTR_OT_view_from_patch, RADTR_OT_load_vector,
           RADTR_OT_toggle_emission, RADTR_OT_export, RADTR_OT_sequence, RADTR_OT_watch, RADTR_OT_sky_factors,
           RADTR_OT_export_gltf, RADTR_OT_view_store, RADTR_OT_view_recall, RADTR_OT_view_remove,
           RADTR_OT_pick_view, RADTR_OT_capture, RADTR_OT_clear)

_register, _unregister = bpy.utils.register_classes_factory(CLASSES)


@bpy.app.handlers.persistent
def _forget_jobs(*_):
    """A file opened or a new one made: the last solve's objects belong to the file left."""
    from .session import running

    running["last"] = None


def register():
    _register()
    bpy.app.handlers.load_post.append(_forget_jobs)


def unregister():
    if _forget_jobs in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(_forget_jobs)
    _unregister()
