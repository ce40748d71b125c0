"""Names of runs and of their parameters: dotted keys for nested parameters, a label per run.

Runs are named by what differs in their configuration, so the run comparison, the HTML
report and the Rerun views all call one run "r_m=2.5" alike.
"""

from __future__ import annotations

from typing import Any


def flatten(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested parameters as one level of dotted keys ('stack.anfis.model')."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def run_labels(parameters: list[dict[str, Any]]) -> list[str]:
    """A name per run from what differs in its configuration ("r_m=2.5"); "defaults" when nothing does.

    Keys are the flattened parameter names without their section ("stack.r_m" reads "r_m") unless another
    section has a key of that name; runs with equal configurations get "#2", "#3" after their name.
    """
    flat = [flatten(p) for p in parameters]
    keys = sorted({k for f in flat for k in f if len({repr(g.get(k)) for g in flat}) > 1})
    every_leaf = [k.rsplit(".", 1)[-1] for k in {k for f in flat for k in f}]
    short = {k: (leaf if every_leaf.count(leaf) == 1 else k) for k in keys for leaf in [k.rsplit(".", 1)[-1]]}
    names = [", ".join(f"{short[k]}={_short_value(f.get(k))}" for k in keys) or "defaults" for f in flat]
    seen: dict[str, int] = {}
    out = []
    for name in names:
        seen[name] = seen.get(name, 0) + 1
        out.append(name if seen[name] == 1 else f"{name} #{seen[name]}")
    return out


def _short_value(value: Any) -> str:
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(_short_value(v) for v in value) + "]"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)
