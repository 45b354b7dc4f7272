"""The View3D > Sidebar > RadTR panel."""
import bpy

from .main import RADTR_PT_main, RADTR_PT_scenarios

CLASSES = (RADTR_PT_main, RADTR_PT_scenarios)

register, unregister = bpy.utils.register_classes_factory(CLASSES)
