"""Two layers: engine tests (no bpy) and Blender tests (PyPI ``bpy``, add-on registered once,
a fresh empty file per test through the ``blend`` fixture)."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SHARED_OBJ = ROOT.parent / "shared" / "data" / "obj"
sys.path.insert(0, str(ROOT))


@pytest.fixture(scope="session")
def addon(tmp_path_factory):
    """The repository registered as the add-on package ``radtr`` (a symlink, as Blender would)."""
    import bpy  # noqa: F401

    link_dir = tmp_path_factory.mktemp("addon")
    (link_dir / "radtr").symlink_to(ROOT, target_is_directory=True)
    sys.path.insert(0, str(link_dir))
    import radtr

    radtr.register()
    yield radtr
    radtr.unregister()


@pytest.fixture(scope="session")
def gpu(addon):
    """A GPU drawing context for the offscreen form-factor methods."""
    from radtr_addon.formfactors.gpu_context import ensure_gpu_context

    ensure_gpu_context()


@pytest.fixture
def blend(addon):
    """An empty Blender file with the add-on registered; returns ``bpy``."""
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    return bpy


@pytest.fixture
def cornell(blend):
    """The bundled Cornell box in a fresh file; returns ``bpy``."""
    from radtr_addon.blender.scenes import load_bundled

    load_bundled("cornell_box").build(blend)
    return blend
