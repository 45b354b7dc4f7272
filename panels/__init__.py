"""The View3D > Sidebar > RadTR panel and its sub-panels."""
import bpy

from .main import (
    RADTR_PT_flashlight,
    RADTR_PT_form_factors,
    RADTR_PT_main,
    RADTR_PT_research,
    RADTR_PT_scenarios,
    RADTR_PT_views,
)

CLASSES = (RADTR_PT_main, RADTR_PT_form_factors, RADTR_PT_flashlight, RADTR_PT_scenarios, RADTR_PT_views,
           RADTR_PT_research)

register, unregister = bpy.utils.register_classes_factory(CLASSES)
