"""The built extension zip installs into Blender (PyPI bpy), enables, registers its operators
and imports its bundled wheels."""
import os
import subprocess
import sys
import textwrap

import pytest
from conftest import ROOT

INSTALL = textwrap.dedent("""
    import sys, bpy
    bpy.ops.extensions.package_install_files(filepath=sys.argv[-1], repo="user_default",
                                             enable_on_install=True)
    enabled = [m for m in bpy.context.preferences.addons.keys() if m.endswith(".radtr")]
    assert enabled, sorted(bpy.context.preferences.addons.keys())
    for op in ("solve", "subdivide", "clear"):
        getattr(bpy.ops.radtr, op).get_rna_type()
    import scipy.sparse, embreex.rtcore_scene
    import importlib
    flashlight = importlib.import_module(enabled[0] + ".radtr_addon.blender.flashlight")
    print("RADTR-INSTALLED", enabled[0])
    print("RADTR-CACHE", flashlight.cache_folder())
""")


@pytest.fixture(scope="module")
def extension_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    run = subprocess.run([sys.executable, str(ROOT / "tools" / "build_extension.py"), "--out", str(out)],
                         capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stdout + run.stderr
    return run.stdout.strip().splitlines()[-1]


def test_zip_installs_and_registers(extension_zip, tmp_path):
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(tmp_path / "user"))
    run = subprocess.run([sys.executable, "-c", INSTALL, extension_zip], capture_output=True, text=True,
                         timeout=600, env=env, cwd=tmp_path)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-3000:]
    line = next(x for x in run.stdout.splitlines() if x.startswith("RADTR-INSTALLED"))
    assert "bl_ext.user_default.radtr" in line
    # the low-rank cache lands in the extension's own user folder, not the temp folder
    cache = next(x for x in run.stdout.splitlines() if x.startswith("RADTR-CACHE")).split(" ", 1)[1]
    assert cache.startswith(str(tmp_path / "user")) and cache.endswith("user_default/radtr/lowrank"), cache
    site = list((tmp_path / "user").glob("extensions/.local/lib/python3.*/site-packages"))
    assert site, "the extension's wheels were not installed"
    for package in ("scipy", "embreex", "pyopencl"):
        assert (site[0] / package).is_dir(), package
