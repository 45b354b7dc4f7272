"""The View3D > Sidebar > RadTR panel."""
import bpy

from .main import RADTR_PT_main

CLASSES = (RADTR_PT_main,)

register, unregister = bpy.utils.register_classes_factory(CLASSES)
