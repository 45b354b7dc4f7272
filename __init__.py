"""RadTR: radiosity global illumination for Blender.

The engine lives in ``radtr_addon`` (numpy, no window needed); this package registers the
Scene settings, the operators (Subdivide, Solve, Clear) and the View3D > Sidebar > RadTR panel.
Submodules are imported in ``register`` so that importing this file alone (as test
collectors do) needs neither ``bpy`` nor a parent package.
"""


def _modules():
    from . import operators, panels, properties

    return (properties, operators, panels)


def register():
    for module in _modules():
        module.register()


def unregister():
    for module in reversed(_modules()):
        module.unregister()
