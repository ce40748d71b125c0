"""Why a detector did (not) flag an epoch: one short line per detecting method, for the views at the cursor.

Each line names the statistic the detector compared, its value, the threshold and the
outcome, in the statistic's own unit: chi_square's f2 against its chi-square gate;
dual_threshold's two tests (f2 over the gate, the CUSUM of the predicted error over h,
flagged when either exceeds 1); the ANFIS family's output against T2 (metres);
cusum_drift's max(S+, S-) against h, with the residual summed and its allowance k;
anfis_hybrid's output against its false-alarm-rate threshold, with its named inputs;
drift_reference's min(|drift_z|, h_z·|drift_residual_m|/T1) against h_z in sd where drift_z
exists, else |drift_residual_m| (the range against the DR error reference) against h_m in metres.
Lines are plain ASCII: the Rerun viewer aborts on a glyph its font lacks.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from replay.events import EpochResult
from replay.stack.features import EXTRA_FEATURES

ANFIS_FAMILY: frozenset[str] = frozenset({"anfis", "anfis_aqpso", "anfis_compensation"})
# the detectors' short names in one-line events, so a line fits the viewer's event panel
SHORT_NAMES: dict[str, str] = {"chi_square": "chi2", "dual_threshold": "dual", "anfis": "anfis", "anfis_aqpso": "aqpso",
                               "anfis_compensation": "comp", "cusum_drift": "cusum", "anfis_hybrid": "hybrid",
                               "drift_reference": "dref"}


def short_names(methods: list[str]) -> str:
    """Methods by their short names, comma-separated."""
    return ", ".join(SHORT_NAMES.get(m, m) for m in methods)
# short names of the hybrid inputs, as the model sees them (magnitudes; f2 as its square root)
_SHORT = {"f2": "sqrt f2", "repeat_count": "repeats", "dr_residual_m": "|dr|", "leader_consistency_m": "|consist.|",
          "usbl_residual_m": "|usbl|", "lag_residual_m": "|lag|", "drift_residual_m": "|drift|",
          "exclusion_residual_m": "|excl.|", "drift_z": "|drift_z|", "exclusion_z": "|excl_z|"}


def wide_features(r: EpochResult) -> np.ndarray:
    """An epoch's feature vector in FEATURE_NAMES order (f1, f2, f3, then EXTRA_FEATURES), as wide detectors take."""
    return np.array([r.f1, r.f2, r.f3, *(getattr(r, n) for n in EXTRA_FEATURES)], dtype=float)


def _cmp(flagged: bool) -> str:
    return ">" if flagged else "<="


def _num(v: float, digits: int = 2) -> str:
    return f"{v:.{digits}f}" if math.isfinite(v) else "n/a"


def _chi_square(r: EpochResult) -> str:
    return f"f2 {_num(r.score)} {_cmp(r.flagged)} gate {_num(r.threshold)}"


def _dual_threshold(r: EpochResult, det: Any) -> str:
    chi2 = float(getattr(det, "chi2_threshold", math.nan))
    abrupt = r.f2 / chi2 if chi2 > 0 else math.nan
    if r.flagged or not hasattr(det, "cusum_state"):
        # after an alarm the runner restarted the CUSUM: the score is the larger of the two ratios
        drift = r.score if not (abrupt >= r.score - 1e-12) else math.nan
        drift_text = _num(drift) if math.isfinite(drift) else f"<= {_num(r.score)}"
    else:
        drift_text = _num(float(det.cusum_state) / float(det.cusum_h))
    which = (" (abrupt)" if abrupt > 1.0 else " (drift)") if r.flagged else ""
    return f"f2/gate {_num(abrupt)}, drift S/h {drift_text}; max {_cmp(r.flagged)} 1{which}"


def _anfis(r: EpochResult) -> str:
    extra = ", range corrected" if r.compensated else ", isolated" if r.isolated else ", capped" if r.capped else ""
    return f"output {_num(r.score)} m {_cmp(r.flagged)} T2 {_num(r.threshold)} m{extra}"


def _cusum_drift(r: EpochResult, det: Any) -> str:
    ex = det.explain(wide_features(r)) if hasattr(det, "explain") else None
    unit = " m" if ex is not None and ex.input.endswith("_m") else " sd"
    text = f"S {_num(r.score)} {_cmp(r.flagged)} h {_num(r.threshold)}{unit}"
    if ex is not None:
        text += f" ({ex.input} {ex.residual_m:+.2f}, k {ex.allowance_m:.2f})"
    return text


def _anfis_hybrid(r: EpochResult, det: Any) -> str:
    text = f"output {_num(r.score)} m {_cmp(r.flagged)} thr {_num(r.threshold)} m"
    if hasattr(det, "explain"):
        ex = det.explain(wide_features(r))
        text += "; " + ", ".join(f"{_SHORT.get(n, n)} {v:.3g}" for n, v in zip(ex.input_names,
                                                                               np.ravel(ex.inputs), strict=True))
    return text


def _drift_reference(r: EpochResult, det: Any) -> str:
    # the decision is in sd where drift_z exists and the detector tests it (h_z), else in metres (h_m)
    h_z = float(getattr(det, "threshold_z", math.nan)) if det is not None else math.nan
    in_sd = math.isfinite(r.drift_z) and (det is None or math.isfinite(h_z))
    if in_sd:
        return (f"score {_num(r.score)} {_cmp(r.flagged)} h {_num(r.threshold)} sd "
                f"(drift_z {r.drift_z:+.2f}, residual {r.drift_residual_m:+.1f} m, needs > T1 too)")
    return f"|drift residual| {_num(r.score)} m {_cmp(r.flagged)} h {_num(r.threshold)} m"


def why_line(r: EpochResult, detector: Any | None = None) -> str:
    """One line: the statistic `r.method` compared at this epoch, its threshold and the outcome.

    `detector` is the trained detector of the epoch's leader (None: only the result's score and
    threshold are shown).
    """
    if not math.isfinite(r.score):
        return "not judged (a feature is missing at this epoch)"
    m = r.method
    if m == "chi_square":
        return _chi_square(r)
    if m == "dual_threshold":
        return _dual_threshold(r, detector)
    if m in ANFIS_FAMILY:
        return _anfis(r)
    if m == "cusum_drift":
        return _cusum_drift(r, detector)
    if m == "anfis_hybrid":
        return _anfis_hybrid(r, detector)
    if m == "drift_reference":
        return _drift_reference(r, detector)
    return f"score {r.score:.3g} {_cmp(r.flagged)} threshold {r.threshold:.3g}"
