"""Operators: Subdivide, Solve, Continue, Flashlight and Clear (thin: gather settings, call the engine, report)."""
import bpy

from .clear import RADTR_OT_clear
from .flashlight import RADTR_OT_flashlight
from .solve import RADTR_OT_resume, RADTR_OT_solve
from .subdivide import RADTR_OT_subdivide

CLASSES = (RADTR_OT_subdivide, RADTR_OT_solve, RADTR_OT_resume, RADTR_OT_flashlight, RADTR_OT_clear)

register, unregister = bpy.utils.register_classes_factory(CLASSES)
