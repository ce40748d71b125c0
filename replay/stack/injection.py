"""The anomaly model of the hybrid training database: pre-defined anomalies injected into one link's ranges.

Paper A trains on "an initial hybrid database of pre-defined abnormal
measurement information". The runner makes ``InjectionConfig.copies``
copies of its training window and injects, per leader link, each kind into
its configured share of the epochs (exactly ``round(share · n)`` epochs
when the link has room; a kind never lands on an epoch another kind took):

- ``stale``: segments of U(stale_min_s, stale_max_s) seconds repeating the
  last range replied before the segment (the modem repeats what it last had);
- ``drift``: segments of U(drift_s) seconds whose error ramps from 0 at
  U(drift_rate_mps) m/s, sign at random;
- ``outlier``: one epoch off by U(outlier_min_m, outlier_max_m), sign at random;
- ``dropout``: one epoch with no reply (removed).

This is the simulator's anomaly model (samples/anomalies.py, whose sizes
are the defaults of `InjectionConfig`), written here as parameters: replay
does not import the simulator. Order as the simulator's: dropouts remove,
drifts and outliers add, stale segments freeze; ranges stay >= 1 m.
"""

from __future__ import annotations

import numpy as np

from replay.stack.config import ConfigError, InjectionConfig

INJECTED_KINDS: tuple[str, ...] = ("stale", "drift", "outlier", "dropout")
NORMAL: str = "normal"
"""The kind of an injected copy's epoch that was left untouched."""


def _segments(t: np.ndarray, free: np.ndarray, target: int, durations: tuple[float, float],
              rng: np.random.Generator) -> list[np.ndarray]:
    """Runs of free, consecutive epochs, each spanning a drawn duration, totalling `target` epochs."""
    out: list[np.ndarray] = []
    left = target
    for _ in range(50 * max(target, 1)):
        if left <= 0 or not free.any():
            break
        start = int(rng.choice(np.flatnonzero(free)))
        end_t = t[start] + rng.uniform(*durations)
        stop = start
        while stop + 1 < t.size and free[stop + 1] and t[stop + 1] <= end_t and stop + 1 - start < left:
            stop += 1
        idx = np.arange(start, stop + 1)
        free[idx] = False
        out.append(idx)
        left -= idx.size
    return out


def inject_link(t_s: np.ndarray, slant_m: np.ndarray, cfg: InjectionConfig,
                rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One link's ranges (time order) after injection: (ranges, replied mask, kind per epoch: a kind or "normal")."""
    t = np.asarray(t_s, dtype=float)
    z = np.asarray(slant_m, dtype=float).copy()
    n = t.size
    kinds = np.full(n, NORMAL, dtype=object)
    replied = np.ones(n, dtype=bool)
    free = np.ones(n, dtype=bool)
    shares = {"stale": cfg.stale_share, "drift": cfg.drift_share, "outlier": cfg.outlier_share,
              "dropout": cfg.dropout_share}
    if any(not 0.0 <= v <= 1.0 for v in shares.values()) or sum(shares.values()) > 1.0:
        raise ConfigError(f"injection shares must be in [0, 1] and sum to <= 1, got {shares}")
    stale = _segments(t, free, round(cfg.stale_share * n), (cfg.stale_min_s, cfg.stale_max_s), rng)
    drifts = _segments(t, free, round(cfg.drift_share * n), cfg.drift_s, rng)
    singles = {}
    for kind in ("outlier", "dropout"):
        k = min(round(shares[kind] * n), int(free.sum()))
        idx = rng.choice(np.flatnonzero(free), size=k, replace=False) if k else np.zeros(0, dtype=int)
        free[idx] = False
        singles[kind] = np.sort(idx)
    replied[singles["dropout"]] = False
    kinds[singles["dropout"]] = "dropout"
    for idx in drifts:
        rate = rng.uniform(*cfg.drift_rate_mps) * (1.0 if rng.random() < 0.5 else -1.0)
        z[idx] = np.maximum(z[idx] + rate * (t[idx] - t[idx[0]]), 1.0)
        kinds[idx] = "drift"
    o = singles["outlier"]
    size = rng.uniform(cfg.outlier_min_m, cfg.outlier_max_m, o.size) * np.where(rng.random(o.size) < 0.5, -1, 1)
    z[o] = np.maximum(z[o] + size, 1.0)
    kinds[o] = "outlier"
    for idx in sorted(stale, key=lambda a: int(a[0])):
        before = np.flatnonzero(replied[: idx[0]])
        z[idx] = z[before[-1]] if before.size else z[idx[0]]
        kinds[idx] = "stale"
    return z, replied, kinds
