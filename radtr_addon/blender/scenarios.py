"""Lighting scenarios in the .blend: solved radiosities of the last solve's patches, kept on
the Scene (``scene.radtr.scenarios``: a name and a weight each, the float32 B in the item's
``B`` custom property with the key of the patches it was solved on) and shown as their
weighted sum in the result meshes, or under the flashlight's light."""
from __future__ import annotations

import hashlib

import numpy as np

from ..lowrank.flashlight import Scenario, blend
from .named import add_named


def patches_key(leaves) -> str:
    """A short hash of the patches' geometry: scenarios solved on other patches do not mix."""
    h = hashlib.sha1(np.ascontiguousarray(leaves.triangles).tobytes())
    h.update(np.ascontiguousarray(leaves.vertices, dtype=np.float32).tobytes())
    return h.hexdigest()[:16]


def store(settings, job, name: str):
    """A new scenario item holding ``job``'s solved B under ``name``, at weight 0 (while every
    weight is 0 the meshes show the last solve)."""
    item = add_named(settings.scenarios, name)
    item["B"] = np.asarray(job.result.B, dtype=np.float32).ravel()
    item["key"] = patches_key(job.leaves)
    return item


def usable(settings, job) -> tuple[list[Scenario], list[str]]:
    """The scenarios of ``settings`` solved on ``job``'s patches, and a warning for each other."""
    key = patches_key(job.leaves)
    out, warnings = [], []
    for item in settings.scenarios:
        if item.get("key") != key or "B" not in item:
            warnings.append(f"lighting scenario '{item.name}' was solved on other patches; solve again with "
                            f"the same patch settings and store it again")
            continue
        out.append(Scenario(item.name, np.asarray(item["B"], dtype=np.float64).reshape(-1, 3), item.weight))
    return out, warnings


def show_blend(settings, job) -> list[str]:
    """Write the weighted sum of the usable scenarios into ``job``'s result meshes, or the
    solve's own B when no weight is above 0 (none stored, all at 0, the last removed); warnings."""
    from .flashlight import LiveMeshes

    scenarios, warnings = usable(settings, job)
    weighted = [sc for sc in scenarios if sc.weight > 0]
    B = blend(weighted, job.leaves.n) if weighted else job.result.B
    LiveMeshes(job.objects, job.leaves).write(B)
    return warnings
