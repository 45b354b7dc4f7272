"""Scenes to solve: bundled scenes (``scenes/*.py``, built by script), .blend and .obj files.

``open_scene(source)`` makes one the current Blender file; a bundled scene module is loaded by
path (it is not part of the engine) and builds itself with ``build(bpy)``.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

from ..errors import InputFileError, RadTRError

SCENES_DIR = Path(__file__).resolve().parents[2] / "scenes"


def bundled_scenes() -> list[str]:
    return sorted(p.stem for p in SCENES_DIR.glob("*.py") if not p.stem.startswith("_"))


def load_bundled(name: str):
    """The module of bundled scene ``name`` (loaded by path: it is not part of the engine)."""
    path = SCENES_DIR / f"{name}.py"
    if not path.is_file():
        raise RadTRError(f"no bundled scene '{name}' (have: {', '.join(bundled_scenes())})")
    spec = importlib.util.spec_from_file_location(f"radtr_scene_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def open_scene(source: str) -> list[str]:
    """Make ``source`` the current Blender file; returns warnings from loading it."""
    import bpy

    path = Path(source)
    if path.suffix.lower() == ".blend":
        if not path.is_file():
            raise InputFileError(f"{path}: no such file")
        try:
            bpy.ops.wm.open_mainfile(filepath=str(path))
        except RuntimeError as exc:
            reason = str(exc).strip().removeprefix("Error: ")
            raise InputFileError(f"{path}: not a .blend file Blender can read ({reason})") from None
        return []
    bpy.ops.wm.read_homefile(use_empty=True)
    if path.suffix.lower() == ".obj":
        from .objfile import load_obj

        return load_obj(path)
    load_bundled(source).build(bpy)
    return []
