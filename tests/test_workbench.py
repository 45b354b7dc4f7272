"""The research workbench in Blender's UI: Export, Sky Form Factors, Sequence and Watch as
operators on the last solve, each writing the same files as the command line does."""
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT
from test_viewpoints import pixels

from radtr_addon.exchange import load
from radtr_addon.sky import dome_size

#: One set of settings, as Scene properties and as CLI flags.
SETTINGS = dict(max_area=0.02, levels=2, method="embree", rays=64, tolerance=1e-3)
FLAGS = ["--max-area", "0.02", "--levels", "2", "--method", "embree", "--rays", "64", "--tolerance", "1e-3"]


def cli(*args, timeout=300):
    run = subprocess.run([sys.executable, "-m", "radtr_addon", *args], cwd=ROOT, capture_output=True, text=True,
                         timeout=timeout)
    assert run.returncode == 0, run.stderr[-2000:]
    return run


@pytest.fixture
def solved(cornell):
    bpy = cornell
    s = bpy.context.scene.radtr
    for k, v in SETTINGS.items():
        setattr(s, k, v)
    assert bpy.ops.radtr.solve() == {"FINISHED"}
    return bpy


def test_export_operator_writes_what_the_cli_writes(solved, tmp_path):
    bpy = solved
    assert bpy.ops.radtr.export(filepath=str(tmp_path / "op.npz"), format="NPZ", level=1) == {"FINISHED"}
    cli("export", "cornell_box", "--out", str(tmp_path / "cli.npz"), "--level", "1", *FLAGS)
    op, ref = load(tmp_path / "op.npz"), load(tmp_path / "cli.npz")
    assert set(op) == set(ref) and {"F", "U", "V"} <= set(op)
    assert (op["F"] != ref["F"]).nnz == 0 and op["F"].nnz > 0
    np.testing.assert_array_equal(op["U"], ref["U"])
    np.testing.assert_array_equal(op["emission"], ref["emission"])


def test_sky_operator_gives_the_cli_sky_matrix_and_a_view_a_point(solved, tmp_path):
    bpy = solved
    assert bpy.ops.radtr.sky_factors(alpha=30, beta=45, resolution=64, images=True,
                                     out_dir=str(tmp_path / "views")) == {"FINISHED"}
    assert len(list((tmp_path / "views").glob("sky_*.png"))) == dome_size(30, 45) == 24
    assert bpy.ops.radtr.export(filepath=str(tmp_path / "op.npz"), format="NPZ") == {"FINISHED"}
    cli("export", "cornell_box", "--out", str(tmp_path / "cli.npz"), "--sky", "uniform", "--sky-step", "30",
        "--sky-altitude-step", "45", "--sky-resolution", "64", *FLAGS)
    op, ref = load(tmp_path / "op.npz"), load(tmp_path / "cli.npz")
    assert op["sky"].shape == (24, op["F"].shape[0]) and op["sky"].nnz > 0
    assert (op["sky"] != ref["sky"]).nnz == 0
    np.testing.assert_array_equal(op["sky_directions"], ref["sky_directions"])


def test_sequence_and_watch_operators_render_what_the_cli_renders(solved, tmp_path):
    from radtr_addon.blender.extract import RESULT_COLLECTION

    bpy = solved
    n = sum(len(o.data.polygons) for o in bpy.data.collections[RESULT_COLLECTION].objects)
    E = np.zeros((n, 3))
    E[::7] = 5.0
    for i, scale in ((1, 1.0), (2, 3.0)):
        np.savetxt(tmp_path / f"e{i}.dat", scale * E)
    before = pixels(bpy, _render(bpy, tmp_path / "before.png"))
    assert bpy.ops.radtr.sequence(prefix=str(tmp_path / "e"), suffix=".dat", first=1, last=2,
                                  out_dir=str(tmp_path / "op"), out_prefix="shot_") == {"FINISHED"}
    assert bpy.ops.radtr.watch(file=str(tmp_path / "e2.dat"), period=0.05, polls=3, out_dir=str(tmp_path / "opw"),
                               out_prefix="look_") == {"FINISHED"}
    np.testing.assert_array_equal(pixels(bpy, _render(bpy, tmp_path / "after.png")), before)   # colours restored
    cli("sequence", "cornell_box", "--prefix", str(tmp_path / "e"), "--suffix", ".dat", "--to", "2",
        "--out-dir", str(tmp_path / "cli"), "--out-prefix", "shot_", *FLAGS)
    cli("watch", "cornell_box", "--file", str(tmp_path / "e2.dat"), "--polls", "3", "--interval", "0.05",
        "--out-dir", str(tmp_path / "cliw"), "--out-prefix", "look_", *FLAGS)
    for ours, theirs in (("op/shot_0001.png", "cli/shot_0001.png"), ("op/shot_0002.png", "cli/shot_0002.png"),
                         ("opw/look_0000.png", "cliw/look_0000.png")):
        a, b = pixels(bpy, tmp_path / ours), pixels(bpy, tmp_path / theirs)
        assert np.abs(a - b).max() < 2 / 255, ours
    assert np.abs(pixels(bpy, tmp_path / "op/shot_0002.png") - pixels(bpy, tmp_path / "op/shot_0001.png")).max() > 0.1


def _render(bpy, path):
    from radtr_addon.blender.render import render_png

    render_png(bpy.context.scene, str(path))
    return path
