"""Items of the Scene's RadTR collections (lighting scenarios, saved views) are found by name."""
from __future__ import annotations


def add_named(collection, name: str):
    """A new item of a Blender collection property named ``name``, or ``name 2``, ``name 3``
    ... when that is taken (items are set and recalled by name: keep names apart)."""
    taken = {item.name for item in collection}
    unique, k = name, 2
    while unique in taken:
        unique, k = f"{name} {k}", k + 1
    item = collection.add()
    item.name = unique
    return item
