"""Bundled scenes: each module builds one scene in the current Blender file with ``build()``."""
