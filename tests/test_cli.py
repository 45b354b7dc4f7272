"""Batch use: ``python -m radtr_addon solve`` writes a .blend and a PNG a person can look at;
``bench skeleton --quick`` prints its table and JSON."""
import json
import os
import re
import subprocess
import sys

import numpy as np
from conftest import ROOT


def run(*args, cwd=ROOT):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "radtr_addon", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env=env)


def test_solve_bundled_scene_writes_blend_and_png(tmp_path, blend):
    out = run("solve", "cornell_box", "--max-area", "0.006", "--resolution", "32", "--tolerance", "0.01",
              "--out", str(tmp_path / "r.blend"), "--render", str(tmp_path / "r.png"))
    assert out.returncode == 0, out.stderr[-2000:]
    assert "energy balance error" in out.stdout
    # the power books as shares: they add up, and light leaves through the open front
    books = dict((name, float(x)) for name, x in re.findall(r"(absorbed|escaped|blocked|unshot) ([\d.]+)%", out.stdout))
    assert abs(sum(books.values()) - 100) < 0.3, books
    assert books["escaped"] > 5 and books["absorbed"] > 30, books
    blend.ops.wm.open_mainfile(filepath=str(tmp_path / "r.blend"))
    assert len(blend.data.collections["RadTR"].objects) == 8
    img = blend.data.images.load(str(tmp_path / "r.png"))
    px = np.array(img.pixels[:]).reshape(img.size[1], img.size[0], 4)[::-1]   # top row first
    top, left, right = px[55:90, 200:312, :3], px[200:300, 20:60, :3], px[200:300, -60:-20, :3]
    assert top.max() > 0.99                                   # the light, seen in the ceiling
    assert left[..., 0].mean() > 1.3 * left[..., 1].mean()      # red wall on the left
    assert right[..., 1].mean() > 1.3 * right[..., 0].mean()    # green wall on the right


def test_unknown_scene_is_a_clear_error():
    out = run("solve", "no_such_scene")
    assert out.returncode == 2 and "no bundled scene 'no_such_scene'" in out.stderr


def test_bench_skeleton_quick(tmp_path):
    out = run("bench", "skeleton", "--quick", "--json", str(tmp_path / "b.json"))
    assert out.returncode == 0, out.stderr[-2000:]
    assert "form_factors" in out.stdout
    rows = json.loads((tmp_path / "b.json").read_text())
    assert rows[0]["patches"] > 800 and rows[0]["shots"] > 0


def test_bench_formfactors_quick_orders_the_settings(tmp_path):
    out = run("bench", "formfactors", "--quick", "--json", str(tmp_path / "f.json"), cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert (tmp_path / "out" / "formfactors.png").stat().st_size > 10_000
    tables = json.loads((tmp_path / "f.json").read_text())
    rms = {r["method"]: r["rms_error"] for r in tables["methods"]}
    split = {r["mode"]: r for r in tables["split modes"]}
    assert list(split) == ["none", "triangle", "centre", "uniform", "diagonal", "adaptive"]
    assert all(split[m]["row_sum_error"] < split["none"]["row_sum_error"] for m in split if m != "none")
    assert rms["hemicube 256"] < rms["hemicube 64"] / 2
    assert rms["paraboloid 256 split adaptive 0.002"] < rms["paraboloid 256 split none"] / 5
    assert rms["embree 4096 rays"] < rms["embree 256 rays"] / 2


def test_bench_solvers_quick(tmp_path):
    out = run("bench", "solvers", "--quick", "--json", str(tmp_path / "s.json"), cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-2000:]
    assert (tmp_path / "out" / "solvers.png").stat().st_size > 10_000
    tables = json.loads((tmp_path / "s.json").read_text())
    seed = tables["seed"]
    assert {r["form_factors"] for r in seed} == {"paraboloid 128 split none", "hemicube 64", "embree 256 rays"}
    assert all(r["rows"] <= r["shots"] and r["total_s"] > 0 for r in seed)
    acc = {r["solver"]: r for r in tables["accuracy"]}
    floors = [acc[m]["floor"] for m in ("shooting", "jacobi", "gauss_seidel", "direct")]
    assert max(floors) - min(floors) < 0.01 * max(floors)       # all converge to the same patch solution
    assert acc["cycles 64 spp"]["floor"] < acc["cycles 16 spp"]["floor"]
    prec = {(r["solver"], r["precision"]): r["error_vs_direct"] for r in tables["precision"]}
    assert prec[("shooting", "float64")] < 1e-6 and prec[("shooting", "float32")] < 1e-4
    coarse, fine = tables["floor"][0], tables["floor"][1]
    assert coarse["triangles"] < fine["triangles"] and coarse["error_vs_cycles"] > fine["error_vs_cycles"]


def test_flashlight_poses_render_pngs_and_bad_poses_are_clear(tmp_path):
    poses = tmp_path / "poses.json"
    eye = [0.278, 0.8, 0.273]                  # the Cornell camera, looking into the open box
    first = {"position": eye, "direction": [0, -1, -0.3]}
    second = {"position": eye, "direction": [0.3, -1, 0], "angle_deg": 10, "color": [1, 0.5, 0.2]}
    poses.write_text(json.dumps([first, second, [first, second]]))
    args = ("--max-area", "0.004", "--levels", "2", "--method", "embree", "--rays", "64", "--tolerance", "0.01")
    out = run("flashlight", "cornell_box", "--poses", str(poses), "--out-dir", str(tmp_path / "f"), *args)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "built" in out.stdout
    pngs = sorted((tmp_path / "f").glob("*.png"))
    assert [p.name for p in pngs] == ["flashlight_000.png", "flashlight_001.png", "flashlight_002.png"]
    assert len({p.read_bytes() for p in pngs}) == 3          # each pose lights, two spots at once a third way
    again = run("flashlight", "cornell_box", "--poses", str(poses), "--out-dir", str(tmp_path / "f"), *args)
    assert "read from the cache" in again.stdout
    poses.write_text('[{"position": [0, 0, 0]}]')
    bad = run("flashlight", "cornell_box", "--poses", str(poses), "--out-dir", str(tmp_path / "f"), *args)
    assert bad.returncode == 2 and "poses.json" in bad.stderr and "Traceback" not in bad.stderr


def test_export_writes_what_other_programs_read(tmp_path):
    from radtr_addon.exchange import load, load_text

    args = ("--max-area", "0.01", "--levels", "2", "--method", "embree", "--rays", "64")
    out = run("export", "cornell_box", "--out", str(tmp_path / "box.npz"), "--level", "1", *args)
    assert out.returncode == 0, out.stderr[-2000:]
    a = load(tmp_path / "box.npz")
    n = len(a["areas"])
    assert a["F"].shape == (n, n) and a["U"].shape[0] == n and a["V"].shape[0] == n
    sums = np.asarray(a["F"].sum(axis=1)).ravel()
    assert sums.max() <= 1 + 1e-12 and sums.mean() > 0.5            # what each patch sees, the rest escapes
    assert a["emission"].max() > 0 and a["triangles"].shape == (n, 9)
    out = run("export", "cornell_box", "--out", str(tmp_path / "box"), *args)
    assert out.returncode == 0 and "box_ffs.dat" in out.stdout
    t = load_text(tmp_path / "box")
    assert abs(t["F"] - a["F"]).max() < 1e-15 and "U" not in t


def test_sequence_from_exported_emission(tmp_path):
    args = ("--max-area", "0.01", "--method", "embree", "--rays", "32", "--tolerance", "0.01")
    out = run("export", "cornell_box", "--out", str(tmp_path / "box"), *args)
    assert out.returncode == 0, out.stderr[-2000:]
    es = np.loadtxt(tmp_path / "box_es.dat")
    for i in (1, 2):
        np.savetxt(tmp_path / f"em{i}.dat", es * i)
    out = run("sequence", "cornell_box", "--prefix", str(tmp_path / "em"), "--suffix", ".dat", "--to", "2",
              "--out-dir", str(tmp_path / "seq"), *args)
    assert out.returncode == 0, out.stderr[-2000:]
    assert sorted(p.name for p in (tmp_path / "seq").glob("*.png")) == ["frame_0001.png", "frame_0002.png"]
    np.savetxt(tmp_path / "em3.dat", es[:-1])
    bad = run("sequence", "cornell_box", "--prefix", str(tmp_path / "em"), "--suffix", ".dat", "--from", "3",
              "--to", "3", "--out-dir", str(tmp_path / "seq"), *args)
    assert bad.returncode == 2 and "em3.dat" in bad.stderr and "rows" in bad.stderr


def test_backends_lists_each_backend_with_its_device_or_reason():
    from radtr_addon.lowrank.backends import BACKENDS, unavailable

    out = run("backends")
    lines = dict(line.split(": ", 1) for line in out.stdout.splitlines())
    assert set(lines) == set(BACKENDS), out.stdout
    for name in BACKENDS:
        reason = unavailable(name)
        assert lines[name] == f"unavailable: {reason}" if reason else lines[name].startswith("available")
    assert lines["opencl"].startswith("unavailable") or " on " in lines["opencl"]      # the device it runs on
    assert out.returncode == int(any(unavailable(name) for name in BACKENDS))
    assert run("backends", "numpy").returncode == 0
    bad = run("backends", "cuda")
    assert bad.returncode == 2 and "no back-end named cuda" in bad.stderr
