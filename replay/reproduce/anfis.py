"""`auvreplay reproduce anfis`: every method on the sample (or a given) trial, beside paper A's table.

The trial goes the way a user's would: logs -> `record` -> archive ->
`replay`. Both ANFIS model modes are run (per leader, as paper A does, and
one shared model), since a per-leader model that saw no anomaly in its
training window cannot flag one later (docs/design.md section 10).
"""

from __future__ import annotations

import dataclasses
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from recorders.manifest import ManifestError, load_manifest
from recorders.record import record
from replay.engine.config import RunConfig
from replay.errors import UserError
from replay.run.config import load_config
from replay.run.pipeline import replay_archive

# Paper A, section 4 table, 600-1700 s, 462 epochs of which 57 anomalous
PAPER_A: dict[str, dict[str, int]] = {
    "chi_square": {"tp": 23, "tn": 388, "fp": 17, "fn": 34},
    "dual_threshold": {"tp": 34, "tn": 387, "fp": 18, "fn": 23},
    "anfis": {"tp": 47, "tn": 401, "fp": 4, "fn": 10},
}
PAPER_EPOCHS, PAPER_ANOMALOUS = 462, 57


def sample_trial_dir() -> Path:
    """The bundled sample lake trial's directory."""
    from importlib.resources import files

    return Path(str(files("samples") / "lake_trial"))


def archive_for(trial: str | Path | None, workdir: Path) -> Path:
    """An archive for the trial: an .mcap as given, or a trial directory (or its manifest) recorded."""
    path = Path(trial) if trial is not None else sample_trial_dir()
    if path.is_file() and path.suffix == ".mcap":
        return path
    manifest_path = path / "trial.toml" if path.is_dir() else path
    if not manifest_path.is_file():
        raise UserError(f"{trial}: not an archive (.mcap), a trial directory with trial.toml, or a manifest")
    try:
        manifest = load_manifest(manifest_path)
        out = workdir / "trial.mcap"
        record(manifest, out)
    except ManifestError as exc:
        raise UserError(str(exc)) from exc
    return out


def run_modes(archive: Path, base: RunConfig) -> dict[str, dict[str, Any]]:
    """Metrics of the per-leader and the shared ANFIS model mode on one archive."""
    out = {}
    for mode in ("per_leader", "shared"):
        stack = dataclasses.replace(base.stack, anfis=dataclasses.replace(base.stack.anfis, model=mode))
        outcome = replay_archive(archive, dataclasses.replace(base, stack=stack), write_output=False)
        out[mode] = outcome.metrics
    return out


def _rates(tp: int, tn: int, fp: int, fn: int) -> tuple[float, float, float]:
    total = tp + tn + fp + fn
    return (tp + tn) / total, fp / max(fp + tn, 1), fn / max(fn + tp, 1)


def format_report(modes: dict[str, dict[str, Any]]) -> str:
    """The paper's table with ours beside it, for both model modes, plus error percentiles."""
    lines = []
    for mode, metrics in modes.items():
        lines.append(f"\nANFIS model: {mode}; run {metrics['run_id']}; window {metrics['window'][0]:.0f}-"
                     f"{metrics['window'][1]:.0f} s; epochs {metrics['epochs']} (paper {PAPER_EPOCHS}), "
                     f"anomalous {metrics['anomalous']} (paper {PAPER_ANOMALOUS})")
        lines.append(f"{'method':<20}{'TP':>5}{'TN':>5}{'FP':>5}{'FN':>5}{'ACC':>7}{'FPR':>7}{'FNR':>7}{'AUC':>7}"
                     f"{'R@5%':>7}  | paper{'TP':>5}{'TN':>5}{'FP':>5}{'FN':>5}{'ACC':>7}{'FPR':>7}{'FNR':>7}")
        for method, m in metrics["methods"].items():
            if m.get("tp") is None:
                continue
            acc, fpr, fnr = _rates(m["tp"], m["tn"], m["fp"], m["fn"])
            row = (f"{method:<20}{m['tp']:>5}{m['tn']:>5}{m['fp']:>5}{m['fn']:>5}{acc:>7.3f}{fpr:>7.3f}{fnr:>7.3f}"
                   f"{_f(m.get('auc')):>7}{_f(m.get('recall_at_fpr_5')):>7}  |")
            p = PAPER_A.get(method)
            if p:
                pa, pf, pn = _rates(p["tp"], p["tn"], p["fp"], p["fn"])
                row += f"      {p['tp']:>5}{p['tn']:>5}{p['fp']:>5}{p['fn']:>5}{pa:>7.3f}{pf:>7.3f}{pn:>7.3f}"
            lines.append(row)
        lines.append(f"{'method':<20}{'err p50 m':>10}{'err p90 m':>10}{'err rms m':>10}")
        for method, m in metrics["methods"].items():
            if m.get("error_p50_m") is not None:
                lines.append(f"{method:<20}{_f(m['error_p50_m']):>10}{_f(m['error_p90_m']):>10}"
                             f"{_f(m['error_rms_m']):>10}")
    return "\n".join(lines)


def _f(v: Any) -> str:
    return "-" if v is None else f"{v:.3f}" if abs(v) < 100 else f"{v:.1f}"


def reproduce(trial: str | Path | None = None, overrides: Sequence[str] = ()) -> dict[str, dict[str, Any]]:
    """Record (if needed) and replay the trial in both model modes."""
    base = load_config(None, list(overrides))
    with tempfile.TemporaryDirectory(prefix="auvreplay-") as tmp:
        archive = archive_for(trial, Path(tmp))
        return run_modes(archive, base)


def json_object(modes: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The result object (docs/design.md section 6) of the paper's mode (per leader), with both modes under `modes`."""
    out = dict(modes["per_leader"])
    out["modes"] = modes
    out["paper"] = {"epochs": PAPER_EPOCHS, "anomalous": PAPER_ANOMALOUS, "methods": PAPER_A}
    return out
