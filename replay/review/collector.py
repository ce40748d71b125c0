"""Collecting a run into ReviewData for the views (only when a reviewer asked for it: --rrd, the API)."""

from __future__ import annotations

import math
from bisect import bisect_left
from collections.abc import Mapping, Sequence
from itertools import repeat
from operator import attrgetter
from typing import Any

import numpy as np
import pandas as pd

from replay.engine.layout import TrialLayout
from replay.events import (
    EpochResult,
    ErrorSample,
    Fix,
    Listener,
    RunResults,
    TrainedDetectors,
    UsblEpoch,
)
from replay.navigation.review import DR_METHOD, NavigationReview
from replay.review.columns import column
from replay.review.data import ReviewData
from replay.review.track_table import RAD, TrackTable
from replay.stack.detectors.why_text import epoch_features
from replay.stack.features import EXTRA_FEATURES
from replay.stack.methods import anfis_models, detecting_names, short_names, why_line
from replay.stack.model import horizontal_offset_m, offset_to_latlon

INS_DECIMATE_S = 1.0
# mission seconds are float differences of ns times: a 1 Hz source's 1.4 - 0.4 is 0.9999999999999999 s
DECIMATE_SLACK_S = 1e-6

PAPER_INPUTS = ("f1", "f2", "f3")
"""The inputs of paper A's ANFIS detectors (a wide detector names its own: `inputs`)."""

COLUMNS: dict[str, tuple[str, ...]] = {
    "ranges": ("t_s", "follower", "leader", "measured_m", "true_m", "residual_m", "leader_east_m", "leader_north_m",
               "horizontal_m"),
    "detections": ("t_s", "follower", "leader", "method", "flagged", "score", "threshold", "f1_innovation_m",
                   "f2_mahalanobis2", "f3_r_adapted_m2", "label", "isolated", "capped", *EXTRA_FEATURES, "why"),
    "errors": ("t_s", "follower", "method", "error_m"),
    "anfis_epochs": ("model", "epoch", "rmse", "params"),
    "anfis_explain": ("t_s", "model", "inputs", "memberships", "firing", "output", "threshold", "flagged"),
    "kmcdf": ("t_s", "target", "method", "east_m", "north_m", "fixes_east_m", "fixes_north_m", "fixes_cluster",
              "nodes_east_m", "nodes_north_m", "delay_normal", "phase_normal", "nodes"),
    "events": ("t_s", "level", "text"),
}
"""Each table's columns but the tracks', in order: its rows are tuples (anfis_explain's lists, filled later) of
these."""
_EXPLAIN = COLUMNS["anfis_explain"].index("inputs")     # where an anfis_explain row's explanation starts
_extra = attrgetter(*EXTRA_FEATURES)


def frame(columns: Sequence[str], rows: Sequence[Sequence[Any]]) -> pd.DataFrame:
    """A frame of rows (tuples in the order of `columns`), built column by column."""
    return pd.DataFrame(dict(zip(columns, map(column, zip(*rows, strict=True)), strict=True)))


def anfis_core(det: Any) -> Any | None:
    """The trained ANFIS model of a detector: the detector itself, or the one a wide detector wraps (anfis_hybrid);
    None for anything else or before training."""
    core = getattr(det, "anfis", det)
    return core if hasattr(core, "snapshots") and getattr(core, "trained", False) else None


def decimated(ts: list[float], last: float, gap: float) -> tuple[list[int], float]:
    """The indexes of the times `position` keeps (each at least `gap` after the last kept) and the last kept time.

    Sorted times (a block's, as a rule) jump from kept point to kept point by bisection; the test on each
    candidate is the one of a sample at a time (t - last < gap), so the same points are kept.
    """
    keep: list[int] = []
    n = len(ts)
    if any(b < a for a, b in zip(ts, ts[1:])):       # out of order: one at a time
        for i, t in enumerate(ts):
            if not t - last < gap:
                keep.append(i)
                last = t
        return keep, last
    i = 0
    while i < n:
        # every time below last + gap less a margin far above rounding fails the test: skip them at once
        i = bisect_left(ts, last + gap - 1e-6 * gap, i)
        while i < n and ts[i] - last < gap:
            i += 1
        if i < n:
            keep.append(i)
            last = ts[i]
            i += 1
    return keep, last


class ReviewCollector(Listener):
    """Keeps rows for every ReviewData table while the engine runs."""

    def __init__(self, run_id: str, trial: dict[str, Any], t0_ns: int, layout: TrialLayout,
                 parameters: dict[str, Any] | None = None):
        self.run_id, self.trial, self.t0_ns, self.layout = run_id, trial, t0_ns, layout
        self.parameters = dict(parameters or {})
        self._label: dict[tuple[str, str], tuple[int, float, int]] = {}    # (follower, leader) -> label, since, n
        # with one follower, events need not name it
        self._many = sum(role == "follower" for role in dict(layout.roles).values()) > 1
        self._origin: tuple[float, float] | None = None
        self.rows: dict[str, list[Any]] = {k: [] for k in COLUMNS if k != "errors"}    # each table's rows (COLUMNS)
        # the errors (a row per method at every GPS fix: the most rows after the tracks) as columns of floats and
        # strings: a tuple a row would start a garbage collection every few hundred rows
        self._errors: tuple[list[float], list[str], list[str], list[float]] = ([], [], [], [])
        self._tracks = TrackTable()
        self._last_drawn: dict[tuple[str, str], float] = {}    # (vehicle, source) -> its last track point
        self._models: dict[str, TrainedDetectors] = {}
        self._detecting = detecting_names()     # the method table's detectors, in its order
        self._anfis = frozenset(anfis_models()) & frozenset(self._detecting)
        self._detectors: dict[str, dict[str, dict[str, Any]]] = {}     # follower -> method -> leader -> detector
        # anfis_explain rows of plain ANFIS detectors waiting for their model's internals, per detector (its id):
        # the detector, the epochs' features and their rows; `_explain_pending` fills them, one call a detector
        self._unexplained: dict[int, tuple[Any, list[list[float]], list[list[Any]]]] = {}

    def origin(self, lat_rad: float, lon_rad: float) -> None:
        self._tracks.set_origin(lat_rad, lon_rad)     # rows before keep the origin they were collected under
        self._origin = (lat_rad, lon_rad)

    def _en(self, lat: float, lon: float) -> tuple[float, float]:
        if self._origin is None:
            return math.nan, math.nan
        n, e = horizontal_offset_m(lat, lon, *self._origin)
        return float(e), float(n)

    def count(self, name: str) -> int:
        """How many rows the table `name` has so far."""
        return len(self._tracks) if name == "tracks" else len(self._errors[0]) if name == "errors" else \
            len(self.rows[name])

    def table(self, name: str, start: int = 0) -> pd.DataFrame | None:
        """The rows of table `name` from `start` on, as a frame; None when there are none."""
        if name == "errors":
            if start >= len(self._errors[0]):
                return None
            return pd.DataFrame(dict(zip(COLUMNS[name], (column(c[start:]) for c in self._errors), strict=True)))
        if name != "tracks":
            if name == "anfis_explain":
                self._explain_pending()
            rows = self.rows[name][start:]
            return frame(COLUMNS[name], rows) if rows else None
        return self._tracks.frame(start)

    def position(self, vehicle: str, source: str, fix: Fix) -> None:
        if source != "gps":       # INS and other solutions come at tens of Hz: one point a second is a track
            key = (vehicle, source)
            last = self._last_drawn.get(key, -math.inf)
            if fix.t_s - last < INS_DECIMATE_S - DECIMATE_SLACK_S:
                return
            self._last_drawn[key] = fix.t_s
        self._tracks.add(fix.t_s, vehicle, source, fix.lat_rad, fix.lon_rad)

    def positions(self, vehicle: str, source: str, t_s: Any, lat_rad: Any, lon_rad: Any, depth_m: Any) -> None:
        """A block's positions: the rows `position` would keep of each (one a second but GPS), east/north at once."""
        ts = t_s.tolist()
        if source == "gps":
            keep = list(range(len(ts)))
        else:
            key = (vehicle, source)
            keep, last = decimated(ts, self._last_drawn.get(key, -math.inf), INS_DECIMATE_S - DECIMATE_SLACK_S)
            if keep:
                self._last_drawn[key] = last
        if not keep:
            return
        idx = np.asarray(keep)
        lat = np.asarray(lat_rad, dtype=float)[idx]
        lon = np.asarray(lon_rad, dtype=float)[idx]
        self._tracks.add_many([ts[i] for i in keep], vehicle, [source] * len(keep), lat.tolist(), lon.tolist())

    def estimates(self, follower: str, t_s: float, est: Mapping[str, tuple[float, ...]]) -> None:
        if est:     # a row per method, its standard deviations from the variances (east-east, north-north)
            lat, lon, nn, _ne, ee = zip(*est.values(), strict=True)
            self._tracks.add_many([t_s] * len(lat), follower, list(est), lat, lon, ee, nn)

    def epoch(self, follower: str, results: list[EpochResult], leader_fix: Fix | None) -> None:
        r0 = results[0]
        le, ln = self._en(leader_fix.lat_rad, leader_fix.lon_rad) if leader_fix else (math.nan, math.nan)
        truth = getattr(r0, "truth_range_m", math.nan)
        self.rows["ranges"].append((r0.time_s, follower, r0.leader, r0.range_m, truth, r0.range_m - truth, le, ln,
                                    r0.range_m))
        models = self._models.get(follower)
        self._interval(follower, r0)
        if models is not None and r0.time_s > models.training_end_s:
            self._verdict_event(follower, [r for r in results if r.method in self._detecting])
        dets = self._detectors.get(follower, {}) if models is not None and r0.time_s > models.training_end_s else None
        extra = _extra(r0)        # the same for every method of an epoch
        detections = self.rows["detections"]
        for r in results:
            if r.method not in self._detecting:
                continue
            detections.append((r.time_s, follower, r.leader, r.method, bool(r.flagged), r.score, r.threshold, r.f1,
                               r.f2, r.f3, int(r.label), bool(r.isolated), bool(r.capped), *extra,
                               why_line(r, dets.get(r.method, {}).get(r.leader)) if dets is not None else ""))
            if r.method in self._anfis and models is not None and r.time_s > models.training_end_s:
                self._explain(follower, models, r)

    def _who(self, follower: str, leader: str) -> str:
        return f"{follower}/{leader}" if self._many else leader

    def _interval(self, follower: str, r: EpochResult) -> None:
        """Anomaly intervals of the truth labels: an event where one starts and where it ends."""
        key = (follower, r.leader)
        last, since, n = self._label.get(key, (0, r.time_s, 0))
        label = int(r.label)
        if label == 1 and last != 1:
            self.event(r.time_s, "INFO", f"ANOMALY STARTS {self._who(follower, r.leader)}")
            since, n = r.time_s, 0
        elif label != 1 and last == 1:
            self.event(r.time_s, "INFO", f"ANOMALY ENDS {self._who(follower, r.leader)}: {n} epochs, "
                                         f"{since:.0f}-{r.time_s:.0f} s")
        self._label[key] = (label, since, n + (label == 1))

    def _verdict_event(self, follower: str, results: list[EpochResult]) -> None:
        """One line per epoch where a detector flagged or the truth is anomalous; WARN on a miss or false alarm."""
        if not results:
            return
        r0 = results[0]
        who = self._who(follower, r0.leader)
        flagged = [r for r in results if r.flagged]
        if r0.label != 1 and not flagged:
            return
        err = f"err {r0.range_m - r0.truth_range_m:+.1f} m"
        hit = [r.method for r in flagged]
        quiet = [r.method for r in results if not r.flagged]
        n = len(results)
        # name the shorter list (short names), so that a line fits the event panel; the why view has the scores
        if r0.label == 1:
            if not quiet:
                self.event(r0.time_s, "INFO", f"HIT {who} by all {n}; {err}")
            elif not hit:
                self.event(r0.time_s, "WARN", f"MISS {who}: all {n}; {err}")
            elif len(quiet) <= len(hit):
                self.event(r0.time_s, "WARN", f"MISS {who}: {short_names(quiet)}; {err}")
            else:
                self.event(r0.time_s, "WARN", f"MISS {who}: {len(quiet)} of {n} (hit: {short_names(hit)}); {err}")
        elif r0.label == 0:
            text = short_names(hit) if len(hit) <= len(quiet) or not quiet else \
                f"{len(hit)} of {n} (quiet: {short_names(quiet)})"
            self.event(r0.time_s, "WARN", f"FALSE ALARM {who}: {text}; {err}")
        else:
            self.event(r0.time_s, "INFO", f"FLAGGED {who} (no truth label): {short_names(hit)}")

    def _model_key(self, method: str, follower: str, leader: str) -> str:
        """An ANFIS model's name in anfis_epochs and anfis_explain: "<method>/<leader>" (or its follower/leader)."""
        return f"{method}/{self._who(follower, leader)}"

    def _explain(self, follower: str, models: TrainedDetectors, r: EpochResult) -> None:
        det: Any = models.detectors(r.method).get(r.leader)
        if anfis_core(det) is None:
            return
        row = [r.time_s, self._model_key(r.method, follower, r.leader), None, None, None, math.nan, r.threshold,
               bool(r.flagged)]
        self.rows["anfis_explain"].append(row)
        if hasattr(det, "explain_rows"):     # explained with the detector's other epochs when a table is taken
            _, features, rows = self._unexplained.setdefault(id(det), (det, [], []))
            features.append([r.f1, r.f2, r.f3])
            rows.append(row)
            return
        # a wide detector (anfis_hybrid) turns the epoch's feature row into its model's inputs itself
        ex = det.explain(epoch_features(r)) if hasattr(det, "anfis") else det.explain(np.array([r.f1, r.f2, r.f3]))
        self._explained([row], getattr(ex, "anfis", ex))

    def _explain_pending(self) -> None:
        """The waiting anfis_explain rows' inputs, memberships, firing and output: `explain_rows` per detector."""
        for det, features, rows in self._unexplained.values():
            self._explained(rows, det.explain_rows(np.array(features)))
        self._unexplained.clear()

    @staticmethod
    def _explained(rows: list[list[Any]], ex: Any) -> None:
        """Fill anfis_explain rows from an explanation of as many epochs (or of one, without its row axis)."""
        inputs, mu = np.asarray(ex.normalized_inputs).tolist(), np.asarray(ex.memberships).tolist()
        firing, output = np.asarray(ex.normalized_firing).tolist(), np.asarray(ex.output).tolist()
        if len(rows) == 1 and np.ndim(ex.output) == 0:
            inputs, mu, firing, output = [inputs], [mu], [firing], [output]
        for k, row in enumerate(rows):
            row[_EXPLAIN:_EXPLAIN + 4] = inputs[k], mu[k], firing[k], float(output[k])

    def errors(self, follower: str, samples: list[ErrorSample]) -> None:
        if samples:
            t, method, error = zip(*samples, strict=True)
            cols = self._errors
            cols[0].extend(t)
            cols[1].extend(repeat(follower, len(t)))
            cols[2].extend(method)
            cols[3].extend(error)

    def trained(self, follower: str, models: TrainedDetectors, t_s: float) -> None:
        self._models[follower] = models
        self._detectors[follower] = {m: dict(models.detectors(m)) for m in self._detecting}
        for method in self._detecting:
            if method not in self._anfis:
                continue
            for leader, det in models.detectors(method).items():
                core = anfis_core(det)
                if core is None:
                    continue
                about = {"method": method, "leader": leader, "trainer": core.trainer,
                         "inputs": list(getattr(det, "inputs", PAPER_INPUTS)), "compensation": core.compensation,
                         "training_samples": core.training_samples}
                model = self._model_key(method, follower, leader)
                for snap in core.snapshots():
                    self.rows["anfis_epochs"].append((model, int(snap.epoch), float(snap.training_rmse), {
                        "a": snap.a.tolist(), "b": snap.b.tolist(), "c": snap.c.tolist(),
                        "consequents": snap.consequents.tolist(), "input_min": snap.input_min.tolist(),
                        "input_max": snap.input_max.tolist(), "threshold": float(core.threshold),
                        "rule_structure": snap.rule_structure, **about}))

    def usbl(self, epoch: UsblEpoch, positions: dict[str, tuple[float, float]]) -> None:
        # the preliminary fixes as columns, not PreliminaryFix objects (the same numbers)
        fix_e, fix_n, fix_cluster = epoch.fix.fix_columns() if "kmcdf2" in positions else ([], [], [])
        # the epoch's arrays as lists once, shared by its methods' rows (review tables are read, not changed)
        nodes_e, nodes_n = epoch.node_en[:, 0].tolist(), epoch.node_en[:, 1].tolist()
        delay, phase = np.asarray(epoch.fix.delay_normal).tolist(), np.asarray(epoch.fix.phase_normal).tolist()
        nodes = list(epoch.nodes)
        for method, (e, n) in positions.items():
            if self._origin is not None and math.isfinite(e) and math.isfinite(n):
                lat, lon = offset_to_latlon(n, e, *self._origin)
                self._tracks.add_placed(epoch.t_s, epoch.target, method, lat, lon, e, n)
            fixes = method == "kmcdf2"
            self.rows["kmcdf"].append((epoch.t_s, epoch.target, method, e, n, fix_e if fixes else [],
                                       fix_n if fixes else [], fix_cluster if fixes else [], nodes_e, nodes_n, delay,
                                       phase, nodes))

    def event(self, t_s: float, level: str, text: str) -> None:
        self.rows["events"].append((t_s, level, text))

    def finished(self, follower: str, results: RunResults) -> None:
        pass

    def finish(self, metrics: dict[str, Any], navigation: Mapping[str, NavigationReview] | None = None) -> ReviewData:
        """The collected ReviewData; each navigation review's dead reckoning becomes a track (one point a second)."""
        for vehicle, nav in (navigation or {}).items():
            dr = nav.dead_reckoning
            keep = np.isfinite(dr.lat_deg) & np.isfinite(dr.lon_deg)
            t, lat, lon = dr.t_s[keep], dr.lat_deg[keep], dr.lon_deg[keep]
            # the first sample of each second (none for a vehicle whose DR never started: no DVL or no heading)
            second = np.diff(np.floor(t / INS_DECIMATE_S), prepend=-np.inf) > 0
            lat_s, lon_s = lat[second], lon[second]
            # radians (la / RAD), whose degrees the table makes back (* RAD)
            lat_r, lon_r = lat_s / RAD, lon_s / RAD
            ts = t[second].tolist()
            self._tracks.add_many(ts, vehicle, [DR_METHOD] * len(ts), lat_r.tolist(), lon_r.tolist())
        for note in metrics.get("notes", []):
            self.event(0.0, "WARN", note)
        # the tables that have rows; the others keep ReviewData's empty frames
        frames = {name: f for name in ("tracks", *COLUMNS) if (f := self.table(name)) is not None}
        origin = self._origin
        data = ReviewData(self.run_id, str(self.trial.get("name", "")), self.t0_ns,
                          origin[0] * RAD if origin else math.nan, origin[1] * RAD if origin else math.nan,
                          dict(self.layout.roles), list(metrics.get("methods", {})), metrics=metrics, **frames)
        data.parameters = self.parameters
        data.navigation = dict(navigation or {})
        data.events = data.events.sort_values("t_s", kind="stable", ignore_index=True)
        return data
