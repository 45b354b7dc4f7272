"""RadTR engine: radiosity on triangle patches, free of ``bpy`` except in ``radtr_addon.blender``.

The add-on (the repository root package) and the command line (``python -m radtr_addon``)
both drive this package; every capability is an engine function first.
"""
