"""Low-rank factors kept on disk, keyed by everything they depend on.

The key hashes the leaf geometry (vertices, triangles), reflectances and emission (a refined
cut follows the light), the clusters of the level and those below, the cut's size, the
form-factor settings and the dtype: any change gives another file. A file holds
the arrays and a SHA-256 of their bytes; one that is truncated, corrupt or from another key
is reported (``warnings``) and rebuilt. In Blender the folder is the extension's user
directory (``bpy.utils.extension_path_user``); in batch any folder.
"""
from __future__ import annotations

import hashlib
import io
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ..errors import InputFileError
from .factor import LowRank, build, build_cut, refined_cut


def cache_key(hierarchy, level: int, ff_label: str, dtype, refine_to: int = 0) -> str:
    leaves = hierarchy.leaves
    h = hashlib.sha256()
    for a in (leaves.vertices, leaves.triangles, leaves.rho, leaves.emission, *hierarchy.cluster[level:],
              *hierarchy.representative[level:]):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(f"{level}|{refine_to}|{ff_label}|{np.dtype(dtype).name}".encode())
    return h.hexdigest()[:32]


def _arrays(lr: LowRank) -> dict:
    out = {"U": lr.U, "V_data": lr.V.data, "V_indices": lr.V.indices, "V_indptr": lr.V.indptr,
           "V_shape": np.array(lr.V.shape), "rho": lr.rho, "level": np.array(lr.level)}
    for c, (lu, piv) in enumerate(lr.lu):
        out[f"lu{c}"], out[f"piv{c}"] = lu, piv
    return out


def _digest(arrays: dict) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        h.update(name.encode())
        h.update(np.ascontiguousarray(arrays[name]).tobytes())
    return h.hexdigest()


def save(lr: LowRank, path: Path, key: str):
    arrays = _arrays(lr)
    buf = io.BytesIO()
    np.savez(buf, key=np.array(key), digest=np.array(_digest(arrays)), **arrays)
    tmp = path.with_suffix(".part")
    tmp.write_bytes(buf.getvalue())
    tmp.replace(path)                    # never a half-written file under the real name


def load(path: Path, key: str) -> LowRank:
    """The factors in ``path``; ValueError when the file is unreadable, corrupt or another key's."""
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {name: z[name] for name in z.files}
    except Exception as exc:                          # truncated zip, bad CRC, not a zip
        raise ValueError(f"{path.name}: unreadable ({type(exc).__name__}: {exc})") from None
    if str(data.pop("key", "")) != key:
        raise ValueError(f"{path.name}: written for other settings")
    digest = str(data.pop("digest", ""))
    if _digest(data) != digest:
        raise ValueError(f"{path.name}: contents do not match their checksum")
    channels = sum(1 for name in data if name.startswith("lu"))
    V = sp.csr_matrix((data["V_data"], data["V_indices"], data["V_indptr"]), shape=tuple(data["V_shape"]))
    lus = [(data[f"lu{c}"], data[f"piv{c}"]) for c in range(channels)]
    return LowRank(data["U"], V, data["rho"], lus, int(data["level"]), {"loaded": 0.0})


def cached_build(hierarchy, rows, level: int, folder: Path, *, ff_label: str, dtype=np.float64,
                 refine_to: int = 0, warnings: list | None = None, **kw) -> tuple[LowRank, bool]:
    """(factors, True if read from the cache): load them when the key matches, else build and
    save. ``refine_to`` > 0 refines the level into a cut of that many clusters (``refined_cut``)."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise InputFileError(f"the low-rank cache folder {folder} is a file")
    folder.mkdir(parents=True, exist_ok=True)
    key = cache_key(hierarchy, level, ff_label, dtype, refine_to)
    path = folder / f"lowrank-{key}.npz"
    if path.is_dir():
        raise InputFileError(f"the low-rank cache file {path} is a folder: remove it")
    if path.exists():
        try:
            return load(path, key), True
        except ValueError as exc:
            if warnings is not None:
                warnings.append(f"low-rank cache {exc}; rebuilding")
    if refine_to > len(hierarchy.representative[level]):
        lr = build_cut(hierarchy, rows, refined_cut(hierarchy, rows, level, refine_to), dtype=dtype, **kw)
    else:
        lr = build(hierarchy, rows, level, dtype=dtype, **kw)
    save(lr, path, key)
    return lr, False
