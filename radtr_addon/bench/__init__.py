"""Benchmarks: ``python -m radtr_addon bench NAME [--quick] [--json FILE]`` prints a table."""
from __future__ import annotations

import json

from ..errors import RadTRError


def print_table(rows: list[dict]):
    """Print ``rows`` (dicts) as an aligned text table; a key a row lacks is a blank cell."""
    keys = list(dict.fromkeys(k for r in rows for k in r))
    cells = [[_fmt(r.get(k, "")) for k in keys] for r in rows]
    widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]
    print("  ".join(k.rjust(w) for k, w in zip(keys, widths)))
    for c in cells:
        print("  ".join(v.rjust(w) for v, w in zip(c, widths)))


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.2e}" if 0 < abs(v) < 0.01 else f"{v:.3f}"
    return str(v)


def run_benchmark(name: str, quick: bool = False, json_path: str | None = None) -> int:
    """Run benchmark ``name``; it returns one table (rows) or several ({title: rows})."""
    from . import adaptive, distributed, formfactors, realtime, skeleton, solvers

    benches = {"skeleton": skeleton.run, "formfactors": formfactors.run, "solvers": solvers.run,
               "realtime": realtime.run, "adaptive": adaptive.run, "distributed": distributed.run}
    if name not in benches:
        raise RadTRError(f"no benchmark '{name}' (have: {', '.join(benches)})")
    rows = benches[name](quick=quick)
    for title, table in (rows.items() if isinstance(rows, dict) else [("", rows)]):
        if title:
            print(f"\n== {title}")
        print_table(table)
    if json_path:
        with open(json_path, "w") as fh:
            json.dump(rows, fh, indent=2)
    return 0
