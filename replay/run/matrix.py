"""The condition matrix of `evaluate --conditions`: every condition with and without USBL, trained and scored.

A condition is a scenario fragment (tables of a scenario TOML: `conditions`,
`ins`, `ranging`...) applied over the base scenario; `all` is
`BUILTIN_CONDITIONS`, and a FILE holds one table per condition, each a
fragment (``[multipath.conditions]`` with ``multipath_per_hour = 6.0``). Each
runs twice: as it is, and with KMCDF's USBL fixes fed to the filters
(``engine.usbl_update = "kmcdf2"``), the second named ``NAME_usbl``.

Per condition the train seed is simulated under that condition and every
test trial is trained on its set (`evaluate`'s "given" training). The
scripted drifts of the test trials take the drift rates in turn (the i-th
test seed the i-th rate, cycling), so drift recall per rate costs no extra
trial. Figures per method, pooled over the condition's test trials:

* ``auc``, ``fnr_at_fpr_1|2|5``: open loop. The operating point is chosen
  on the test trials' own ROC, the same way for every method (the best
  recall at FPR <= target), so it says how well a method separates, not
  how its threshold holds;
* ``fpr_closed``, ``fnr_closed``: closed loop, the method's own decisions:
  the share flagged of the epochs labelled normal, and the share not flagged
  of those labelled anomalous;
* ``recall_by_kind`` (closed loop, as `evaluate`), ``drift_recall_by_rate``
  (rate in m/s as text -> the closed-loop recall of anomalous drift epochs
  at that rate; None without any);
* ``error_p50_m``, ``error_p90_m`` against the follower's GPS.

``label_noise_floor``: the share of the anomalous epochs (|Z_gps - Z| > T1)
that carry no injected anomaly: range and GPS noise, or a condition such as
a sound-speed bias, pushing a normal range past the label threshold. No
detector can tell those from normal ranges.
"""

from __future__ import annotations

import time
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from replay.engine.config import RunConfig
from replay.errors import UserError
from replay.run.evaluate import (
    TrialGroup,
    TrialScores,
    TrialSpec,
    _clean,
    closed_loop_fpr,
    method_figures,
    run_trials,
    split_seeds,
)
from samples.anomalies import KIND_CODES
from samples.scenario import Scenario, ScenarioError, scenario_from_dict, scenario_to_toml

if TYPE_CHECKING:
    from distributed import Client

    from replay.run.evaluate import Progress

USBL_METHOD = "kmcdf2"
"""The positioning method whose fixes the `_usbl` conditions feed to the filters."""
OPERATING_POINT = ("open loop: FNR at FPR 1/2/5 % is read on the test trials' own ROC, the same way for every "
                   "method; closed loop: each method's own threshold, trained on the train seed")

BUILTIN_CONDITIONS: dict[str, dict[str, Any]] = {
    "default": {},
    "sound_speed": {"conditions": {"sound_speed_bias": 0.005}},
    "owtt_clock": {"conditions": {"owtt_clock_offset_s": 1e-3, "owtt_clock_drift_ppm": 1.0}},
    "multipath": {"conditions": {"multipath_per_hour": 6.0}},
    "heavy_tails": {"conditions": {"range_noise_dof": 3.0, "range_noise_per_km_m": 3.0}},
    "dvl_lock_loss": {"conditions": {"dvl_lock_loss_per_hour": 6.0}},
    "compass_deviation": {"conditions": {"compass_deviation_deg": 2.0}},
    "drawn": {"conditions": {"anomalies_drawn": True, "sensor_spread": 0.4}},
    "combined": {"conditions": {
        "sound_speed_bias": 0.003, "owtt_clock_offset_s": 5e-4, "owtt_clock_drift_ppm": 0.5,
        "multipath_per_hour": 4.0, "range_noise_dof": 4.0, "range_noise_per_km_m": 2.0,
        "dvl_lock_loss_per_hour": 4.0, "compass_deviation_deg": 1.5, "anomalies_drawn": True,
        "sensor_spread": 0.3}},
}
"""`--conditions all`: each one of issue 26's conditions alone at a mid-range value, then all together."""


@dataclass(frozen=True)
class Condition:
    """One column of the matrix: its name, its scenario and whether USBL fixes feed the filters."""

    name: str
    scenario: Scenario
    usbl: bool


def _merged(base: Scenario, fragment: Mapping[str, Any], name: str) -> Scenario:
    """The base scenario with a fragment's tables laid over it (keys replace keys, lists replace lists)."""
    data: dict[str, Any] = tomllib.loads(scenario_to_toml(base))
    for key, value in fragment.items():
        if isinstance(value, Mapping) and isinstance(data.get(key), dict):
            data[key] = {**data[key], **value}
        else:
            data[key] = value
    try:
        return scenario_from_dict(data)
    except ScenarioError as exc:
        raise UserError(f"condition {name!r}: {exc}") from None


def conditions(spec: str, base: Scenario | None = None) -> list[Condition]:
    """`all` or a TOML FILE of fragments: every condition, without and with USBL (``_usbl``)."""
    base = base if base is not None else Scenario()
    if spec == "all":
        fragments: Mapping[str, Any] = BUILTIN_CONDITIONS
    else:
        try:
            fragments = tomllib.loads(Path(spec).read_text(encoding="utf-8"))
        except OSError as exc:
            raise UserError(f"--conditions {spec}: cannot read it ({exc.strerror or exc})") from None
        except tomllib.TOMLDecodeError as exc:
            raise UserError(f"--conditions {spec}: {exc}") from None
        if not fragments or not all(isinstance(v, dict) for v in fragments.values()):
            raise UserError(f"--conditions {spec}: expected one table per condition, like [multipath.conditions]")
    out = []
    for name, fragment in fragments.items():
        scenario = _merged(base, fragment, name)
        out += [Condition(name, scenario, False), Condition(f"{name}_usbl", scenario, True)]
    return out


def _config(config: RunConfig, usbl: bool) -> RunConfig:
    engine = replace(config.engine, usbl_update=USBL_METHOD if usbl else "", kmcdf=config.engine.kmcdf or usbl)
    return replace(config, engine=engine, stack=replace(config.stack, training_source="given"))


def label_noise_floor(trials: Sequence[TrialScores]) -> float | None:
    """The share of anomalous epochs with no injected anomaly (one method's rows: every method has the same)."""
    if not trials or not trials[0].methods:
        return None
    m = trials[0].methods[0]
    labels = np.concatenate([t.labels[m] for t in trials])
    kinds = np.concatenate([t.kinds[m] for t in trials])
    anomalous = labels == 1
    return float(np.mean(kinds[anomalous] == KIND_CODES[""])) if anomalous.any() else None


def closed_loop_fnr(trials: Sequence[TrialScores], method: str) -> float | None:
    """The share of a detecting method's anomalous epochs it did not flag, closed loop (None: not detecting)."""
    if not any(method in t.detecting for t in trials):
        return None
    flagged = np.concatenate([t.flagged[method] for t in trials])
    anomalous = np.concatenate([t.labels[method] for t in trials]) == 1
    return float(1.0 - flagged[anomalous].mean()) if anomalous.any() else None


def drift_recall_by_rate(trials: Sequence[TrialScores], method: str) -> dict[str, float | None]:
    """Closed-loop recall of the anomalous drift epochs per drift rate of the trials (text m/s)."""
    out: dict[str, float | None] = {}
    code = KIND_CODES["drift"]
    rates = sorted({t.spec.drift_rate_mps for t in trials if t.spec.drift_rate_mps is not None})
    for rate in rates:
        mine = [t for t in trials if t.spec.drift_rate_mps == rate]
        if not any(method in t.detecting for t in mine):
            out[f"{rate:g}"] = None
            continue
        flagged = np.concatenate([t.flagged[method] for t in mine])
        sel = (np.concatenate([t.labels[method] for t in mine]) == 1) & \
            (np.concatenate([t.kinds[method] for t in mine]) == code)
        out[f"{rate:g}"] = float(flagged[sel].mean()) if sel.any() else None
    return out


def condition_figures(trials: Sequence[TrialScores], methods: Sequence[str]) -> dict[str, Any]:
    """One condition's entry of the JSON: its label-noise floor and every method's figures."""
    rows = {}
    for m in methods:
        f = method_figures(trials, m)
        rows[m] = {"auc": f["auc"], "fnr_at_fpr_1": f["fnr_at_fpr_1"], "fnr_at_fpr_2": f["fnr_at_fpr_2"],
                   "fnr_at_fpr_5": f["fnr_at_fpr_5"], "fpr_closed": closed_loop_fpr(trials, m),
                   "fnr_closed": closed_loop_fnr(trials, m), "recall_by_kind": f["recall_by_kind"],
                   "drift_recall_by_rate": drift_recall_by_rate(trials, m),
                   "error_p50_m": f["error_p50_m"], "error_p90_m": f["error_p90_m"]}
    return {"label_noise_floor": label_noise_floor(trials), "methods": rows}


@dataclass(frozen=True)
class Matrix:
    """What `evaluate --conditions` found, and how long it took."""

    seeds: tuple[int, ...]
    train_seed: int
    conditions: dict[str, dict[str, Any]]
    trial_fpr: dict[str, dict[str, list[float | None]]]     # condition -> method -> each test trial's fpr_closed
    trials: int
    wall_s: float
    cpu_s: float
    workers: str

    def to_json(self) -> dict[str, Any]:
        """The `evaluate --conditions --json` object (module docstring; None for what is undefined)."""
        return _clean({"seeds": list(self.seeds), "train_seed": self.train_seed,
                       "operating_point": OPERATING_POINT, "conditions": self.conditions})


def evaluate_matrix(seeds: Sequence[int], config: RunConfig, conditions_spec: str, train_seed: int | None = None,
                    drift_rates: Sequence[float] = (0.2, 0.3, 0.5), duration_s: float | None = None,
                    client: Client | None = None, progress: Progress | None = None,
                    scenario: Scenario | None = None) -> Matrix:
    """Run every condition of `conditions_spec` ("all" or a FILE) on the test seeds, trained on the train seed."""
    if duration_s is not None and not duration_s > 0:
        raise UserError("--duration must be > 0")
    rates = list(dict.fromkeys(float(r) for r in drift_rates))
    if any(not (np.isfinite(r) and r >= 0) for r in rates):
        raise UserError("--drift-rate: rates must be finite numbers >= 0 (m/s)")
    train, test = split_seeds(list(seeds), train_seed)
    wall0 = time.monotonic()
    jobs = []
    for cond in conditions(conditions_spec, scenario):
        cfg = _config(config, cond.usbl)
        specs = [TrialSpec(s, rates[i % len(rates)] if rates else None, duration_s, cond.scenario)
                 for i, s in enumerate(test)]
        jobs.append((cond, cfg, TrialSpec(train, None, duration_s, cond.scenario), specs))
    try:
        results = run_trials([TrialGroup(cfg, train_spec, tuple(specs)) for _, cfg, train_spec, specs in jobs],
                             client, progress)
    except ScenarioError as exc:
        raise UserError(f"scenario: {exc}") from None
    methods = tuple(config.stack.methods)
    figures, trial_fpr = {}, {}
    for (cond, *_), trials in zip(jobs, results):
        figures[cond.name] = condition_figures(trials, methods)
        trial_fpr[cond.name] = {m: [closed_loop_fpr([t], m) for t in trials] for m in methods
                                if any(m in t.detecting for t in trials)}
    where = "here, one trial at a time" if client is None else \
        f"Dask, {len(client.scheduler_info().get('workers', {}))} workers"
    return Matrix(tuple(test), train, figures, trial_fpr, sum(1 + len(j[3]) for j in jobs),
                  time.monotonic() - wall0, sum(t.cpu_s for ts in results for t in ts), where)


__all__ = ["BUILTIN_CONDITIONS", "OPERATING_POINT", "Condition", "Matrix", "closed_loop_fnr", "condition_figures",
           "conditions", "drift_recall_by_rate", "evaluate_matrix", "label_noise_floor"]
