"""Export and import of the matrices and vectors: exact round trips in every format, and
clear refusals of vectors that do not fit the scene."""
import numpy as np
import pytest
import scipy.sparse as sp
from geometry import cube

from radtr_addon.errors import InputFileError
from radtr_addon.exchange import arrays_of, export, load, load_text, load_vector
from radtr_addon.hierarchy import subdivide


@pytest.fixture
def arrays():
    s = subdivide(cube(), 1 / 4, 1).leaves
    rng = np.random.default_rng(0)
    s.emission[:] = rng.uniform(0, 3, (s.n, 3)) * (rng.uniform(size=(s.n, 1)) < 0.3)
    F = sp.random(s.n, s.n, density=0.3, random_state=1, format="csr")
    U = rng.uniform(size=(s.n, 5)) / 7
    V = sp.csr_matrix((np.ones(s.n) * 1.0, (np.arange(s.n), np.arange(s.n) % 5)), shape=(s.n, 5))
    from radtr_addon.scene import PatchScene
    from radtr_addon.sky import sky_factors

    outward = PatchScene(s.vertices, s.triangles[:, ::-1], s.rho, s.emission, 0, 0)   # so the sky sees it
    sky = sky_factors(outward, 30, 30, resolution=32)
    assert sky.S.nnz > 0
    return arrays_of(s, F, U, V, sky)


def same(a, b):
    if sp.issparse(a):
        return sp.issparse(b) and a.shape == b.shape and np.array_equal(a.toarray(), b.toarray())
    return np.shape(a) == np.shape(b) and np.array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.parametrize("name", ["scene.npz", "scene.mat", "scene"])
def test_round_trip_is_exact(arrays, tmp_path, name):
    files = export(tmp_path / name, arrays)
    back = load(files[0]) if name.endswith(("npz", "mat")) else load_text(tmp_path / name)
    if name == "scene":
        assert sorted(f.name for f in files) == sorted(f"scene{s}" for s in (
            "_ffs.dat", "_U.dat", "_V.dat", "_es.dat", "_ros.dat", "_area.dat", "_triangulo.dat",
            "_sky.dat", "_skydir.dat", "_skypos.dat", "_skyomega.dat"))
    for key, value in arrays.items():
        assert same(value, back[key]), key


def test_vectors_load_from_every_format(arrays, tmp_path):
    n = len(arrays["areas"])
    export(tmp_path / "s.npz", arrays)
    export(tmp_path / "s.mat", arrays)
    export(tmp_path / "s", arrays)
    for f in ("s.npz", "s.mat", "s_es.dat"):
        np.testing.assert_array_equal(load_vector(tmp_path / f, n), arrays["emission"])
    grey = tmp_path / "grey.csv"
    grey.write_text("\n".join(str(v) for v in np.arange(n) / n))
    np.testing.assert_array_equal(load_vector(grey, n)[:, 2], np.arange(n) / n)


@pytest.mark.parametrize("content, message", [
    ("1 2 3\n4 5 6\n", "has 2 rows, the scene has"),
    ("nan 1 1\n" * 48, "row 1 is NaN"),
    ("1 1 1\n" * 10 + "1 -1 1\n" + "1 1 1\n" * 37, "row 11 is negative"),
    ("1 2\n3 4 5\n", "cannot be read"),
    ("1 2 3 4\n" * 48, "rows of 3"),
])
def test_bad_vectors_name_the_file_and_what_is_wrong(tmp_path, content, message):
    f = tmp_path / "bad_es.dat"
    f.write_text(content)
    with pytest.raises(InputFileError, match=message) as err:
        load_vector(f, 48)
    assert "bad_es.dat" in str(err.value)


def test_unreadable_binary_files(tmp_path):
    f = tmp_path / "broken.npz"
    f.write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(InputFileError, match="broken.npz: cannot be read"):
        load_vector(f, 10)
    with pytest.raises(InputFileError, match="no such file"):
        load_vector(tmp_path / "missing.mat", 10)
