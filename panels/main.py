"""RadTR's N-panel: settings, the operators and a live readout (residual, energy) of a running solve."""
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
        col.prop(s, "solver")
        if s.solver == "shooting":
            col.prop(s, "ambient")
        elif s.solver == "user":
            col.prop(s, "user_solver")
        if s.solver == "hierarchical":
            col.prop(s, "quality")
        else:
            col.prop(s, "precision")
        col.prop(s, "tolerance")
        col.prop(s, "max_iterations")
        if s.solver != "hierarchical":
            self.draw_form_factors(col, s)
        col.prop(s, "gather_rays")
        col.prop(s, "sky")
        if s.sky != "none":
            col.prop(s, "sky_radiance")
            col.prop(s, "sky_step")
        col.prop(s, "max_reflectance")
        col.prop(s, "cache_mb")
        col.prop(s, "mode", expand=True)
        row = col.row(align=True)
        row.operator("radtr.solve", icon="LIGHT_SUN")
        row.operator("radtr.resume", icon="PLAY", text="Continue")
        job = running["job"]
        if job is not None:
            solver = job.solver
            box = col.box()
            box.label(text=solver.phase)
            box.label(text=f"Residual {solver.residual:.2e} of emitted (stop at {solver.tol:g})")
            e = solver.energy()
            box.label(text=f"Absorbed {e['absorbed']:.1%}, escaped {e['escaped'] + e['blocked']:.1%}, "
                           f"unshot {e['unshot']:.1%}")
        col.separator()
        col.label(text="Flashlight")
        col.prop(s, "lowrank_level")
        col.prop(s, "lowrank_refine")
        col.prop(s, "lowrank_backend")
        if s.lowrank_backend == "user":
            col.prop(s, "lowrank_user")
        col.operator("radtr.flashlight", icon="LIGHT_SPOT")
        col.separator()
        col.label(text="Views")
        col.prop(s, "display")
        col.prop(s, "exposure")
        col.prop(s, "view_patch")
        col.prop(s, "view_kind")
        row = col.row(align=True)
        row.operator("radtr.patch_view", icon="IMAGE_DATA")
        row.operator("radtr.view_from_patch", icon="VIEW_CAMERA")
        col.operator("radtr.load_vector", icon="FILE_FOLDER")
        col.operator("radtr.toggle_emission", icon="RESTRICT_SELECT_OFF")
        col.operator("radtr.clear", icon="TRASH")

    @staticmethod
    def draw_form_factors(col, s):
        col.label(text="Form Factors")
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


class RADTR_PT_scenarios(bpy.types.Panel):
    """Stored lighting scenarios and their weights (a sub-panel)."""

    bl_label = "Lighting Scenarios"
    bl_idname = "RADTR_PT_scenarios"
    bl_parent_id = "RADTR_PT_main"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "RadTR"

    def draw(self, context):
        s = context.scene.radtr
        col = self.layout.column()
        for i, item in enumerate(s.scenarios):
            row = col.row(align=True)
            row.prop(item, "name", text="")
            row.prop(item, "weight", text="", slider=True)
            row.operator("radtr.scenario_remove", text="", icon="X").index = i
        col.operator("radtr.scenario_add", icon="ADD")
