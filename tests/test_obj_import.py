"""OBJ files through Blender's importer: the Embree Cornell box solves, malformed files
give clear errors or documented repairs, never a traceback."""
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, SHARED_OBJ

from radtr_addon.blender.objfile import load_obj, scan_obj
from radtr_addon.blender.pipeline import solve
from radtr_addon.errors import InputFileError
from radtr_addon.settings import Settings

needs_data = pytest.mark.skipif(not SHARED_OBJ.is_dir(), reason="../shared/data/obj not present")


@needs_data
def test_embree_cornell_box_solves_with_warnings(blend):
    warnings = load_obj(SHARED_OBJ / "cornell_box.obj")
    assert any("'light'" in w and "Ka" in w for w in warnings)
    job = solve(blend.context, Settings(max_area=8000.0, resolution=32, tolerance=1e-2), log=lambda *_: None)
    text = "\n".join(job.stats.warnings)
    assert "material 'white'" in text and "clamped to 0.95" in text
    assert job.result.converged
    light = job.leaves.material_names.index("light")
    assert job.leaves.emission[job.leaves.material_index == light].min() == pytest.approx(3.14159265 * 20)


@needs_data
def test_embree_cornell_box_with_reflectance_one_solves_because_light_escapes(blend):
    """The file's white walls reflect everything (Kd 1). With Max Reflectance 1 they are kept:
    the box is open at the front (its front wall is commented out) and the coloured walls
    absorb the other channels, so light decays and shooting converges. Over a tenth of the
    light escapes (15-25% by channel: the ceiling's reflection of the lamp's back, 0.8 mm above it,
    counts as emitted and is mostly caught between the two)."""
    load_obj(SHARED_OBJ / "cornell_box.obj")
    job = solve(blend.context, Settings(max_area=8000.0, resolution=32, tolerance=1e-2, max_reflectance=1.0),
                log=lambda *_: None)
    r = job.result
    assert job.leaves.rho.max() == 1.0 and not any("clamped" in w for w in job.stats.warnings)
    assert r.converged
    assert np.all(r.escaped > 0.1 * r.emitted)


@needs_data
@pytest.mark.parametrize("name, outcome", [
    ("invalid-face-definition.obj", "error"),
    ("invalid-relative-texture-index.obj", "error"),
    ("invalid-relative-vertex-index.obj", "error"),
    ("issue-140-zero-face-idx.obj", "error"),
    ("issue-161-inconsistent-f.obj", "warn"),
    ("issue-295-trianguation-failure.obj", "ok"),
    ("missing_material_file.obj", "ok"),
    ("no_material.obj", "ok"),
    ("cornell_box_multimaterial.obj", "ok"),
])
def test_malformed_files(blend, name, outcome):
    path = SHARED_OBJ / name
    if outcome == "error":
        with pytest.raises(InputFileError, match=name.replace(".", r"\.")):
            load_obj(path)
        return
    warnings = load_obj(path)
    if outcome == "warn":
        assert any(name in w for w in warnings)
    assert sum(len(o.data.polygons) for o in blend.data.objects if o.type == "MESH") > 0


def test_scan_reports_lines(tmp_path):
    p = tmp_path / "bad.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2\nf 1 2 9\nf 0 1 2\nf -1 -2 -4\n")
    problems, _ = scan_obj(p)
    assert [x.split(":")[1] for x in problems] == ["5", "6", "7", "8"]
    with pytest.raises(InputFileError, match="no such file"):
        scan_obj(tmp_path / "missing.obj")
    binary = tmp_path / "binary.obj"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(InputFileError, match="binary.obj"):
        scan_obj(binary)


@needs_data
def test_cli_reports_bad_file_without_traceback():
    bad = SHARED_OBJ / "issue-140-zero-face-idx.obj"
    out = subprocess.run([sys.executable, "-m", "radtr_addon", "solve", str(bad)], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 2
    assert "RadTR error:" in out.stderr and "issue-140-zero-face-idx.obj" in out.stderr
    assert "Traceback" not in out.stderr
