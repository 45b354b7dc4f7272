"""RadTR's N-panel: settings, the three operators and a live readout of a running solve."""
import bpy

from ..operators.solve import running


class RADTR_PT_main(bpy.types.Panel):
    bl_label = "RadTR"
    bl_idname = "RADTR_PT_main"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "RadTR"

    def draw(self, context):
        s = context.scene.radtr
        col = self.layout.column()
        col.label(text="Patches")
        col.prop(s, "max_area")
        col.prop(s, "levels")
        col.operator("radtr.subdivide", icon="MOD_SUBSURF")
        col.separator()
        col.label(text="Solve")
        col.prop(s, "method")
        if s.method == "embree":
            col.prop(s, "rays")
        else:
            col.prop(s, "resolution")
        if s.method == "hemicube":
            col.prop(s, "rotate")
        elif s.method == "paraboloid":
            col.prop(s, "split")
            if s.split == "uniform":
                col.prop(s, "split_level")
        col.prop(s, "tolerance")
        col.prop(s, "max_iterations")
        col.prop(s, "max_reflectance")
        col.prop(s, "mode", expand=True)
        col.operator("radtr.solve", icon="LIGHT_SUN")
        job = running["job"]
        if job is not None:
            box = col.box()
            box.label(text=f"Shot {job.solver.iterations} of at most {job.solver.max_iterations}")
            box.label(text=f"Unshot power {job.solver.residual:.2e} of emitted")
        col.separator()
        col.prop(s, "exposure")
        col.operator("radtr.clear", icon="TRASH")
