"""Paper A's hybrid database: the training window replayed open loop with anomalies injected into copies.

Each copy injects `config.injection`'s kinds at their shares into every
leader's ranges (`replay.stack.injection.inject_link`), then pushes the
window's DR samples, fixes and ranges in their order through one ACKF
without isolation (the ``ackf`` method); its epochs with GPS truth are the
rows, labelled from the truth like recorded ones (A.27). See docs/design.md.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence

import numpy as np

from replay.events import NAN
from replay.stack.config import StackConfig
from replay.stack.features import FEATURE_NAMES
from replay.stack.filters.ckf import State2, dr_predict, position_update, range_innovation, range_update
from replay.stack.injection import inject_link
from replay.stack.labels import UNKNOWN, label_one
from replay.stack.model import metric_scales_scalar, slant_to_horizontal
from replay.stack.runner_options import Start
from replay.stack.tracking import feature_tracker
from replay.stack.training import TrainingSet

WindowInput = tuple[str, tuple]
"""One input of the training window, in push order: ("dr", (t, fwd, lat, hdg, depth)),
("fix", (t, lat, lon, nn, ne, ee)) or ("range", (t, leader, lat, lon, depth, slant, truth))."""


def rows_to_set(rows: Sequence[tuple], kinds: str | Sequence[str]) -> TrainingSet:
    """A TrainingSet of runner rows (t, leader, features..., Z - Z_gps, label) with their kinds."""
    f = len(FEATURE_NAMES)
    feats = np.array([r[2:2 + f] for r in rows], dtype=float).reshape(-1, f)
    kind_col = np.full(len(rows), kinds, dtype=object) if isinstance(kinds, str) else np.array(kinds, dtype=object)
    return TrainingSet(feats, np.array([r[2 + f] for r in rows], dtype=float),
                       np.array([r[3 + f] for r in rows], dtype=np.int8),
                       np.array([r[1] for r in rows], dtype=object), FEATURE_NAMES, kind_col)


class HybridDatabase:
    """Builds the hybrid database of one runner's training window."""

    def __init__(self, config: StackConfig, leaders: Sequence[str], start: Start) -> None:
        """The copies start where the runner started, with its leaders and configuration."""
        self.config = config
        self.leaders = tuple(leaders)
        self.start = start

    def build(self, window: Sequence[WindowInput]) -> tuple[TrainingSet, str]:
        """The injected copies' rows and a note of the kinds injected ("" when there is nothing to copy)."""
        cfg = self.config.injection
        ranges = [args for kind, args in window if kind == "range"]
        if not ranges or cfg.copies <= 0:
            return TrainingSet.empty(FEATURE_NAMES), ""
        t = np.array([r[0] for r in ranges], dtype=float)
        leaders = np.array([r[1] for r in ranges], dtype=object)
        slant = np.array([r[5] for r in ranges], dtype=float)
        parts: list[TrainingSet] = []
        counts: Counter[str] = Counter()
        for c in range(cfg.copies):
            new_slant, replied = slant.copy(), np.ones(slant.size, dtype=bool)
            kinds = np.full(slant.size, "normal", dtype=object)
            for j, ld in enumerate(self.leaders):
                idx = np.flatnonzero(leaders == ld)
                rng = np.random.default_rng([cfg.seed, c, j])
                new_slant[idx], replied[idx], kinds[idx] = inject_link(t[idx], slant[idx], cfg, rng)
            counts.update(kinds.tolist())
            rows = self.copy_rows(window, new_slant, replied)
            by_epoch = dict(zip(zip(t.tolist(), leaders.tolist()), kinds.tolist()))
            parts.append(rows_to_set(rows, [by_epoch[(r[0], r[1])] for r in rows]))
        total = sum(counts.values())
        note = f"{cfg.copies} copies of {slant.size} epochs: " + ", ".join(
            f"{kind} {n} ({n / total:.1%})" for kind, n in sorted(counts.items()))
        out = parts[0]
        for p in parts[1:]:
            out = out.concat(p)
        return out, note

    def copy_rows(self, window: Sequence[WindowInput], slant_m: np.ndarray, replied: np.ndarray) -> list[tuple]:
        """The window's inputs replayed through one ACKF without isolation, with the given ranges: its rows.

        The same arithmetic, in the same order, as a runner holding only the
        ``ackf`` method (tests/test_exclusion.py checks it against one),
        without the per-method bookkeeping; epochs whose range was not
        ``replied`` are left out. Rows as the runner's training rows: (t,
        leader, features..., Z - Z_gps, label) of the epochs with GPS truth.
        """
        cfg = self.config
        lat0, lon0, depth = float(self.start.lat_rad), float(self.start.lon_rad), float(self.start.depth_m)
        b, a = metric_scales_scalar(lat0, depth)
        state = State2(lat0, lon0, (cfg.p0_m[0] / b) ** 2, 0.0, (cfg.p0_m[1] / a) ** 2)
        tracker = feature_tracker(cfg, self.leaders, self.start)
        t_now, fwd, lat_v, hdg = float(self.start.time_s), 0.0, 0.0, 0.0
        q, r_var, t1 = cfg.q_m_per_s, cfg.r_m ** 2, cfg.t1_m
        rows: list[tuple] = []
        k = 0
        for kind, args in window:
            if kind == "dr":
                t_s, fwd, lat_v, hdg, depth = args
            elif kind == "fix":
                t_s = args[0]
            else:
                k += 1
                if not replied[k - 1]:
                    continue
                t_s = args[0]
            if t_s > t_now:
                state = dr_predict(state, t_s - t_now, fwd, lat_v, hdg, depth, q)
                tracker.propagate(t_s - t_now, fwd, lat_v, hdg, depth)
                t_now = t_s
            if kind == "fix":
                _, lat, lon, nn, ne, ee = args
                b, a = metric_scales_scalar(lat, depth)
                cov = (nn / (b * b), ne / (b * a), ee / (a * a))
                tracker.fix(t_s, lat, lon, cov)
                state = position_update(state, lat, lon, *cov) or state
            elif kind == "range":
                _, leader, llat, llon, ldepth, _, truth = args
                slant = float(slant_m[k - 1])
                z, _ = slant_to_horizontal(slant, depth, ldepth)
                geo = (llat, llon, ldepth)
                inn = range_innovation(state, z, geo, depth, r_var)
                if inn is None:
                    continue
                truth = truth if math.isfinite(truth) else NAN
                label = label_one(z, truth, t1)
                extra = tracker.epoch(t_s, leader, slant, z, depth, geo, None)
                if label != UNKNOWN:
                    rows.append((t_s, leader, *inn.features, *extra, z - truth, label))
                state = range_update(state, inn, r_var, adaptive=True)
        return rows
