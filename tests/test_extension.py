"""The built extension zip (wheels for CPython 3.11 and 3.13) installs into Blender (PyPI bpy),
enables, registers its operators, imports its bundled wheels, solves the Cornell box through
its operators and keeps the flashlight's low-rank cache in its own user folder."""
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
    # solve the bundled Cornell box through the operators, then precompute the flashlight
    bpy.ops.wm.read_homefile(use_empty=True)
    importlib.import_module(enabled[0] + ".radtr_addon.blender.scenes").load_bundled("cornell_box").build(bpy)
    s = bpy.context.scene.radtr
    s.max_area, s.levels, s.method, s.rays = 0.01, 2, "embree", 64
    assert bpy.ops.radtr.solve() == {"FINISHED"}
    job = importlib.import_module(enabled[0] + ".operators.session").running["last"]
    light, meshes, warnings, hit = flashlight.flashlight_for(job, 1)
    print("RADTR-SOLVED", job.leaves.n, len(job.objects), float(job.B.max()), hit)
    print("RADTR-BACKEND", light.backend_name, *warnings)
    print("RADTR-FILES", *sorted(p.name for p in flashlight.cache_folder().iterdir()))
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
    for package in ("scipy", "embreex", "pyopencl", "numba", "llvmlite"):
        assert (site[0] / package).is_dir(), package
    # the flashlight's default back-end runs from the bundled wheels (no fallback to numpy)
    backend = next(x for x in run.stdout.splitlines() if x.startswith("RADTR-BACKEND")).split(" ", 1)[1]
    assert backend == "numba", backend
    n, objects, peak, hit = next(x for x in run.stdout.splitlines() if x.startswith("RADTR-SOLVED")).split()[1:]
    assert int(n) > 100 and int(objects) == 8 and float(peak) > 0 and hit == "False"
    files = next(x for x in run.stdout.splitlines() if x.startswith("RADTR-FILES")).split()[1:]
    assert any(f.endswith(".npz") for f in files), files


def test_zip_carries_wheels_for_both_pythons(extension_zip):
    import zipfile

    names = zipfile.ZipFile(extension_zip).namelist()
    for tag in ("cp311", "cp313"):
        assert sum(f"-{tag}-" in n for n in names) == 6, (tag, [n for n in names if n.endswith(".whl")])
