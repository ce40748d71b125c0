"""Comparing two replay runs: parameters, metrics and per-epoch detections, in mission seconds.

Runs are named by what differs in their configuration (`replay.review.naming.run_labels`); A is the
first argument. Every decision that differs is listed with its truth label, and each run is credited
with the differing decisions it got right (`replay.review.differing`, the rule the viewer's table reads
too).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from formats.mcap_reader import ArchiveReader
from replay.errors import UserError
from replay.review.differing import DetectionKey, decision_word, differing_epochs, truth_word
from replay.review.naming import flatten, run_labels
from replay.review.scoreboard import format_value
from replay.run.mission_time import trial_start_ns
from replay.stack.scoring import RESULT_KEYS


def load_run(path: str | Path) -> tuple[dict[str, Any], dict[DetectionKey, tuple[bool, int]]]:
    """A results archive's `run` metadata (JSON fields decoded, `trial_start_ns` an int) and its detections:
    (flagged, truth label) by (ns from the trial start, follower, leader, method)."""
    with ArchiveReader(path) as reader:
        meta = reader.metadata_json("run")
        if meta is None:
            raise UserError(f"{path}: not a replay results archive (no 'run' metadata record)")
        rid = meta["run_id"]
        start = trial_start_ns(reader, meta)
        topics = [t for t in reader.summary().topics if t.startswith(f"/replay/{rid}/") and t.endswith("/detections")]
        detections = {}
        for m in reader.messages(topics):
            d = m.message
            detections[(m.log_time_ns - start, d.follower, d.leader, d.method)] = (bool(d.flagged), int(d.label))
        meta["damage"] = reader.warning()  # what reading it skipped, for the command's warning line
    meta["trial_start_ns"] = start
    for key in ("configuration", "metrics", "parameters"):
        if isinstance(meta.get(key), str):
            meta[key] = json.loads(meta[key])
    return meta, detections


def compare_runs(a: str | Path, b: str | Path) -> dict[str, Any]:
    """Parameter changes, metric differences (B - A) and epochs whose detections differ."""
    meta_a, det_a = load_run(a)
    meta_b, det_b = load_run(b)
    pa, pb = flatten(meta_a["parameters"]), flatten(meta_b["parameters"])
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
    differing, right = differing_epochs(det_a, det_b)
    label_a, label_b = run_labels([meta_a["parameters"], meta_b["parameters"]])
    return {"a": {"run_id": meta_a["run_id"], "file": str(a), "label": label_a},
            "b": {"run_id": meta_b["run_id"], "file": str(b), "label": label_b},
            "same_input": meta_a.get("input_sha256") == meta_b.get("input_sha256"),
            "parameters": params, "metrics": metrics, "differing_epochs": differing, "right": right,
            "warning": "; ".join(f"{path}: {m['damage']}" for path, m in ((a, meta_a), (b, meta_b)) if m["damage"])
            or None}


def verdict(tally: dict[str, int], name_a: str, name_b: str) -> str:
    """Which run was right on the decisions that differ: 'A (r_m=2.5) right on 7 of 9, B (...) on 2'."""
    a, b, n = tally["a"], tally["b"], tally["epochs"]
    winner = "A was right more often" if a > b else ("B was right more often" if b > a else "a tie")
    return f"{winner}: A ({name_a}) right on {a} of {n}, B ({name_b}) on {b} of {n}"


def format_comparison(result: dict[str, Any], limit: int = 20) -> str:
    """The printed comparison."""
    la, lb = result["a"]["label"], result["b"]["label"]
    lines = [f"A: {la}  (run {result['a']['run_id']}, {result['a']['file']})",
             f"B: {lb}  (run {result['b']['run_id']}, {result['b']['file']})"]
    if not result["same_input"]:
        lines.append("note: the two runs replayed different archives")
    lines.append("parameters changed:" if result["parameters"] else "parameters: identical")
    lines += [f"  {k}: {a!r} -> {b!r}" for k, (a, b) in result["parameters"].items()]
    lines.append(f"{'method':<20} {'metric':<16} {'A':>10} {'B':>10} {'B - A':>10}")
    for method, row in result["metrics"].items():
        for key, v in row.items():
            if v["a"] is None and v["b"] is None:
                continue
            if v["diff"] not in (0, 0.0, None) or key in ("tp", "fp", "fn", "error_p50_m"):
                a, b, d = (format_value(v[k]) for k in ("a", "b", "diff"))
                lines.append(f"{method:<20} {key:<16} {a:>10} {b:>10} {d:>10}")
    if result["differing_epochs"]:
        lines.append("decisions that differ (mission seconds from the trial start; truth: the range's label):")
    for method, rows in result["differing_epochs"].items():
        lines.append(f"{method}: {len(rows)} epochs decided differently; "
                     f"{verdict(result['right'][method], la, lb)}")
        for r in rows[:limit]:
            lines.append(f"  {r['mission_s']:9.1f} s  {r['follower']} <- {r['leader']:<10} "
                         f"A {decision_word(r['a']):<7}  B {decision_word(r['b']):<7}  truth {truth_word(r['label'])}")
        if len(rows) > limit:
            lines.append(f"  ... {len(rows) - limit} more (--limit)")
    if result["right"]:
        total = {k: sum(t[k] for t in result["right"].values()) for k in ("a", "b", "epochs")}
        lines.append(f"all detectors: {verdict(total, la, lb)}")
    else:
        lines.append("detections: the two runs decided every epoch alike")
    return "\n".join(lines)
