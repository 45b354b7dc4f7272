"""The Blender adapter: reads scenes into PatchScene and writes results back (uses ``bpy``)."""
