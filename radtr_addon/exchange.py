"""The matrices and vectors of a solve, to and from files other programs read.

What is written (n patches): the form factors F (sparse, row i = what patch i sees), the
low-rank U (n x k) and V (n x k, sparse) when there are any, emission E and reflectance rho
(n x 3), areas (n) and the triangles (n x 9: the three corners' x, y, z), and with a sky the
sky form factors (points x patches, sparse) with the points' directions, positions and solid
angles. Three formats:

- ``.npz`` (numpy): arrays ``F_data, F_indices, F_indptr, F_shape`` (CSR), ``U``, ``V_*``
  (CSR), ``emission``, ``reflectance``, ``areas``, ``triangles``;
- ``.mat`` (MATLAB, scipy.io): variables ``F`` and ``V`` sparse, the rest dense;
- the seed's plain-text files ``<prefix>_ffs.dat``, ``_U.dat``, ``_V.dat``, ``_es.dat``,
  ``_ros.dat``, ``_area.dat``, ``_triangulo.dat``: whitespace-separated numbers, one row per
  line; the sparse ones as 1-based "row column value" triplets (MATLAB's ``spconvert``).

``load_vector`` reads a per-patch emission or radiosity (n x 3, or n for grey) from any of
them and refuses, naming the file, what is unreadable, of the wrong length, NaN or negative.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp

from .errors import InputFileError

TEXT_SUFFIXES = {"F": "_ffs.dat", "U": "_U.dat", "V": "_V.dat", "emission": "_es.dat",
                 "reflectance": "_ros.dat", "areas": "_area.dat", "triangles": "_triangulo.dat",
                 "sky": "_sky.dat", "sky_directions": "_skydir.dat", "sky_positions": "_skypos.dat",
                 "sky_solid_angles": "_skyomega.dat"}
#: Arrays written with one dimension (the others are matrices).
ONE_DIMENSIONAL = ("areas", "sky_solid_angles")
#: Names a vector may have inside an .npz or .mat file, in the order they are looked for.
VECTOR_NAMES = ("emission", "E", "B", "radiosity", "es")


def arrays_of(scene, F: sp.csr_matrix | None = None, U=None, V=None, sky=None) -> dict:
    out = {"emission": scene.emission, "reflectance": scene.rho, "areas": scene.areas,
           "triangles": scene.vertices[scene.triangles].reshape(-1, 9)}
    if F is not None:
        out["F"] = sp.csr_matrix(F)
    if U is not None:
        out["U"] = np.asarray(U)
    if V is not None:
        out["V"] = sp.csr_matrix(V)
    if sky is not None:                       # sky.SkyFactors: points x patches, and the points
        out.update({"sky": sp.csr_matrix(sky.S), "sky_directions": sky.directions,
                    "sky_positions": sky.positions, "sky_solid_angles": sky.solid_angles})
    return out


def export(path, arrays: dict) -> list[Path]:
    """Write ``arrays`` (from ``arrays_of``) to ``path``: .npz, .mat, or a text prefix. Returns the files."""
    path = Path(path)
    if path.suffix == ".npz":
        flat = {}
        for name, a in arrays.items():
            if sp.issparse(a):
                flat.update({f"{name}_data": a.data, f"{name}_indices": a.indices, f"{name}_indptr": a.indptr,
                             f"{name}_shape": np.array(a.shape)})
            else:
                flat[name] = a
        np.savez(path, **flat)
        return [path]
    if path.suffix == ".mat":
        scipy.io.savemat(path, {k: (a.tocsc() if sp.issparse(a) else a) for k, a in arrays.items()})
        return [path]
    files = []
    for name, a in arrays.items():
        out = path.parent / f"{path.name}{TEXT_SUFFIXES[name]}"
        if sp.issparse(a):
            coo = a.tocoo()
            np.savetxt(out, np.column_stack([coo.row + 1, coo.col + 1, coo.data]), fmt=["%d", "%d", "%.17g"])
        else:
            np.savetxt(out, np.atleast_2d(a.T).T if a.ndim == 1 else a, fmt="%.17g")
        files.append(out)
    return files


def load(path) -> dict:
    """Every array of an .npz or .mat file written by ``export`` (sparse ones as CSR)."""
    path = Path(path)
    try:
        if path.suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                raw = {k: z[k] for k in z.files}
            out = {}
            for k in [k[:-5] for k in raw if k.endswith("_data")]:
                out[k] = sp.csr_matrix((raw.pop(f"{k}_data"), raw.pop(f"{k}_indices"), raw.pop(f"{k}_indptr")),
                                       shape=tuple(raw.pop(f"{k}_shape")))
            return {**out, **raw}
        raw = scipy.io.loadmat(path)
    except Exception as exc:
        raise InputFileError(f"{path}: cannot be read ({type(exc).__name__}: {exc})") from None
    out = {k: (v.tocsr() if sp.issparse(v) else v) for k, v in raw.items() if not k.startswith("__")}
    for k in ONE_DIMENSIONAL:                   # MATLAB keeps every vector as a 1 x n matrix
        if k in out:
            out[k] = out[k].ravel()
    return out


def load_text(prefix) -> dict:
    """The seed's text files of ``prefix`` that exist."""
    prefix = Path(prefix)
    out = {}
    for name, suffix in TEXT_SUFFIXES.items():
        f = prefix.parent / f"{prefix.name}{suffix}"
        if not f.exists():
            continue
        a = _read_text(f) if f.stat().st_size else np.zeros((0, 3))
        if name in ("F", "V", "sky"):
            n = len(_read_text(prefix.parent / f"{prefix.name}{TEXT_SUFFIXES['areas']}"))
            rows = len(_read_text(prefix.parent / f"{prefix.name}{TEXT_SUFFIXES['sky_directions']}")) \
                if name == "sky" else n
            cols = int(a[:, 1].max()) if name == "V" and len(a) else n
            out[name] = sp.csr_matrix((a[:, 2], (a[:, 0].astype(int) - 1, a[:, 1].astype(int) - 1)),
                                      shape=(rows, cols))
        else:
            out[name] = a[:, 0] if name in ONE_DIMENSIONAL else a
    return out


def _read_text(f: Path) -> np.ndarray:
    try:
        a = np.loadtxt(f, ndmin=2)
    except Exception as exc:
        raise InputFileError(f"{f}: cannot be read as rows of numbers ({exc})") from None
    return a


def load_vector(path, n: int) -> np.ndarray:
    """A per-patch vector (n, 3) from .npz, .mat or text (.dat/.txt/.csv); grey (n,) is spread to RGB."""
    path = Path(path)
    if not path.is_file():
        raise InputFileError(f"{path}: no such file")
    if path.suffix in (".npz", ".mat"):
        arrays = load(path)
        name = next((k for k in VECTOR_NAMES if k in arrays), None)
        if name is None:
            raise InputFileError(f"{path}: has none of the arrays {', '.join(VECTOR_NAMES)}")
        a = np.asarray(arrays[name], dtype=float)
    else:
        a = _read_text(path) if path.suffix != ".csv" else _read_csv(path)
    a = np.squeeze(a)
    if a.ndim == 1:
        a = np.repeat(a[:, None], 3, axis=1)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputFileError(f"{path}: expected {n} values or {n} rows of 3, got shape {a.shape}")
    if len(a) != n:
        raise InputFileError(f"{path}: has {len(a)} rows, the scene has {n} patches")
    bad = ~np.isfinite(a).all(axis=1)
    if bad.any():
        raise InputFileError(f"{path}: row {int(np.flatnonzero(bad)[0]) + 1} is NaN or infinite")
    neg = (a < 0).any(axis=1)
    if neg.any():
        raise InputFileError(f"{path}: row {int(np.flatnonzero(neg)[0]) + 1} is negative")
    return a


def _read_csv(f: Path) -> np.ndarray:
    try:
        return np.loadtxt(f, delimiter=",", ndmin=2)
    except Exception as exc:
        raise InputFileError(f"{f}: cannot be read as comma-separated numbers ({exc})") from None
