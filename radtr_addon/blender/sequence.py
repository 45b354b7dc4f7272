"""Emission vectors from files, solved and rendered: numbered sequences and a watched file.

A vector file holds one emission per patch of the solve it was written for (same scene and
settings, hence the same patches: ``exchange``), and is checked by ``exchange.load_vector``.
Each is solved with the job's solver and form factors (``Solve.with_emission``) (rows computed once, then cached), shown
in the result meshes and rendered to a PNG; the meshes' colours are restored afterwards.
``watch`` reloads a file whenever another program rewrites it: a new version is read only when
its size and time stamp have stayed the same for one polling interval, a text file ends with
a line end (a writer stalled inside its last number leaves the right row count), the file did
not change while it was read, and it parses whole as the expected count of finite numbers;
otherwise it is skipped with a warning and tried again the next interval.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..errors import InputFileError
from ..exchange import load_vector
from .flashlight import LiveMeshes
from .render import render_png


def _show(job, meshes, E, png: Path) -> Path:
    meshes.write(job.with_emission(E))
    render_png(job.bl_scene, str(png.resolve()))
    return png


def render_sequence(job, prefix: str, first: int, last: int, out_dir, suffix: str = "") -> list[Path]:
    """One PNG per file ``<prefix><i><suffix>``, i = first..last; every file is checked first."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    vectors = [(i, load_vector(f"{prefix}{i}{suffix}", job.leaves.n)) for i in range(first, last + 1)]
    meshes = LiveMeshes(job.objects, job.leaves)
    saved = meshes.snapshot()
    try:
        return [_show(job, meshes, E, out_dir / f"frame_{i:04d}.png") for i, E in vectors]
    finally:
        meshes.restore(saved)


def read_complete(path: Path, n: int) -> np.ndarray:
    """E (n, 3) from ``path`` if it is complete (see the module docstring), else InputFileError."""
    def signature():
        st = path.stat()
        return st.st_mtime_ns, st.st_size

    before = signature()
    if path.suffix not in (".npz", ".mat"):
        with open(path, "rb") as f:
            f.seek(max(before[1] - 1, 0))
            if f.read(1) not in (b"\n", b"\r"):
                raise InputFileError(f"{path}: its last line has no line end (cut inside its last number?)")
    E = load_vector(path, n)
    if signature() != before:
        raise InputFileError(f"{path}: changed while it was read")
    return E


def watch(job, path, out_dir, polls: int, interval: float = 0.5, sleep=time.sleep, log=print) -> list[Path]:
    """Poll ``path`` ``polls`` times; each complete new version gives ``watch_NNNN.png``."""
    path, out_dir = Path(path), Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    meshes = LiveMeshes(job.objects, job.leaves)
    saved = meshes.snapshot()
    shown, seen, previous = [], None, None
    try:
        for _ in range(polls):
            try:
                st = path.stat()
                signature = (st.st_mtime_ns, st.st_size)
            except FileNotFoundError:
                signature = None
            if signature is not None and signature != seen and signature == previous:
                try:
                    E = read_complete(path, job.leaves.n)
                except (InputFileError, OSError) as exc:
                    log(f"RadTR warning: {exc}; skipped, waiting for a complete file (tried again in {interval:g} s)")
                else:
                    shown.append(_show(job, meshes, E, out_dir / f"watch_{len(shown):04d}.png"))
                    log(f"RadTR: {path.name} changed; rendered {shown[-1]}")
                    seen = signature
            previous = signature
            sleep(interval)
    finally:
        meshes.restore(saved)
    return shown


def toggle_patch(job, origin, direction, emission: np.ndarray) -> tuple[int, np.ndarray]:
    """Click on a patch: (its id or -1, the new emission); the solve is shown in the result meshes."""
    from ..views import pick_patch, toggle_emission

    i = pick_patch(job.leaves, origin, direction)
    if i < 0:
        return i, emission
    E = toggle_emission(emission, i)
    LiveMeshes(job.objects, job.leaves).write(job.with_emission(E))
    return i, E
