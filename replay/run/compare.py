"""Comparing two replay runs: parameters, metrics and per-epoch detections."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from formats.mcap_reader import ArchiveReader
from replay.errors import UserError
from replay.stack.scoring import RESULT_KEYS


def load_run(path: str | Path) -> tuple[dict[str, Any], dict[tuple[float, str, str, str], bool]]:
    """A results archive's `run` metadata (JSON fields decoded) and its detections by (t, follower, leader, method)."""
    with ArchiveReader(path) as reader:
        meta = reader.metadata_json("run")
        if meta is None:
            raise UserError(f"{path}: not a replay results archive (no 'run' metadata record)")
        rid = meta["run_id"]
        topics = [t for t in reader.summary().topics if t.startswith(f"/replay/{rid}/") and t.endswith("/detections")]
        detections = {}
        for m in reader.messages(topics):
            d = m.message
            detections[(m.log_time_ns / 1e9, d.follower, d.leader, d.method)] = bool(d.flagged)
    for key in ("configuration", "metrics", "parameters"):
        if isinstance(meta.get(key), str):
            meta[key] = json.loads(meta[key])
    return meta, detections


def _flatten(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def run_labels(parameters: list[dict[str, Any]]) -> list[str]:
    """A name per run from what differs in its configuration ("r_m=2.5"); "defaults" when nothing does.

    Keys are the flattened parameter names without their section ("stack.r_m" reads "r_m") unless another
    section has a key of that name; runs with equal configurations get "#2", "#3" after their name.
    """
    flat = [_flatten(p) for p in parameters]
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


def compare_runs(a: str | Path, b: str | Path) -> dict[str, Any]:
    """Parameter changes, metric differences (B - A) and epochs whose detections differ."""
    meta_a, det_a = load_run(a)
    meta_b, det_b = load_run(b)
    pa, pb = _flatten(meta_a["parameters"]), _flatten(meta_b["parameters"])
    params = {k: [pa.get(k), pb.get(k)] for k in sorted(set(pa) | set(pb)) if pa.get(k) != pb.get(k)}
    ma, mb = meta_a["metrics"]["methods"], meta_b["metrics"]["methods"]
    metrics: dict[str, dict[str, Any]] = {}
    for method in sorted(set(ma) | set(mb)):
        row = {}
        for key in RESULT_KEYS:
            va, vb = ma.get(method, {}).get(key), mb.get(method, {}).get(key)
            row[key] = {"a": va, "b": vb, "diff": (vb - va) if isinstance(va, (int, float)) and
                        isinstance(vb, (int, float)) else None}
        metrics[method] = row
    differing: dict[str, list[dict[str, Any]]] = {}
    for key in sorted(set(det_a) | set(det_b)):
        fa, fb = det_a.get(key), det_b.get(key)
        if fa != fb:
            t, follower, leader, method = key
            differing.setdefault(method, []).append({"t_s": t, "follower": follower, "leader": leader,
                                                     "a": fa, "b": fb})
    return {"a": {"run_id": meta_a["run_id"], "file": str(a)}, "b": {"run_id": meta_b["run_id"], "file": str(b)},
            "same_input": meta_a.get("input_sha256") == meta_b.get("input_sha256"),
            "parameters": params, "metrics": metrics, "differing_epochs": differing}


def format_comparison(result: dict[str, Any], limit: int = 20) -> str:
    """The printed comparison."""
    lines = [f"A: run {result['a']['run_id']} ({result['a']['file']})",
             f"B: run {result['b']['run_id']} ({result['b']['file']})"]
    if not result["same_input"]:
        lines.append("note: the two runs replayed different archives")
    lines.append("parameters changed:" if result["parameters"] else "parameters: identical")
    lines += [f"  {k}: {a!r} -> {b!r}" for k, (a, b) in result["parameters"].items()]
    lines.append(f"{'method':<20} {'metric':<16} {'A':>10} {'B':>10} {'B - A':>10}")
    for method, row in result["metrics"].items():
        for key, v in row.items():
            if v["a"] is None and v["b"] is None:
                continue
            fmt = (lambda x: "-" if x is None else (f"{x:.3f}" if isinstance(x, float) else str(x)))
            if v["diff"] not in (0, 0.0, None) or key in ("tp", "fp", "fn", "error_p50_m"):
                lines.append(f"{method:<20} {key:<16} {fmt(v['a']):>10} {fmt(v['b']):>10} {fmt(v['diff']):>10}")
    for method, rows in result["differing_epochs"].items():
        lines.append(f"{method}: {len(rows)} epochs decided differently")
        for r in rows[:limit]:
            lines.append(f"  t={r['t_s']:.3f}  {r['follower']} <- {r['leader']}  A={r['a']}  B={r['b']}")
    return "\n".join(lines)
