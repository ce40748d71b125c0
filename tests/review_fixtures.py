"""A synthetic `ReviewData` with every table filled, for the views' tests and benchmarks.

`synthetic_review(seed, n_epochs)` draws a small lake trial: two leaders, one
follower, ranging epochs alternating leaders every 2.4 s, tracks at 1 Hz,
USBL epochs every 5 s, and two ANFIS models trained over `anfis_epochs`
epochs. Values are plausible, not simulated physics; everything is seeded.
"""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd

from replay.review.data import ReviewData

T0_NS = 1_476_237_600_000_000_000          # 2016-10-12T02:00:00Z, the sample trial's start
ORIGIN = (45.70, 126.60)
LEADERS = ("leader1", "leader2")
FOLLOWER = "follower"
FOLLOWER_METHODS = ("dead_reckoning", "ckf", "ackf", "chi_square", "dual_threshold", "anfis", "anfis_aqpso")
DETECTORS = ("chi_square", "dual_threshold", "anfis", "anfis_aqpso")
KMCDF_METHODS = ("kmcdf1", "kmcdf2")
PING_S, USBL_S, TRACK_HZ = 2.4, 5.0, 1.0
N_NODES, MFS, INPUTS = 4, 2, 3
_M_PER_DEG_LAT = 111_132.0


def _latlon(east: np.ndarray, north: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lat = ORIGIN[0] + north / _M_PER_DEG_LAT
    lon = ORIGIN[1] + east / (_M_PER_DEG_LAT * np.cos(np.radians(ORIGIN[0])))
    return lat, lon


def _truth(t: np.ndarray) -> dict[str, np.ndarray]:
    """East/north truth (n, 2) of every vehicle at times t."""
    w = 2 * np.pi / 600.0
    return {
        "leader1": np.column_stack([-300 + 0.8 * t, 200 + 40 * np.sin(w * t)]),
        "leader2": np.column_stack([300 - 0.7 * t, -150 + 30 * np.cos(w * t)]),
        FOLLOWER: np.column_stack([150 * np.sin(w * t), 1.0 * t - 100 + 20 * np.cos(2 * w * t)]),
    }


def _track_rows(vehicle: str, source: str, t: np.ndarray, en: np.ndarray, std: float) -> pd.DataFrame:
    lat, lon = _latlon(en[:, 0], en[:, 1])
    return pd.DataFrame({"t_s": t, "vehicle": vehicle, "source": source, "lat_deg": lat, "lon_deg": lon,
                         "east_m": en[:, 0], "north_m": en[:, 1], "std_east_m": std, "std_north_m": std})


def _tracks(rng: np.random.Generator, t: np.ndarray) -> pd.DataFrame:
    truth = _truth(t)
    parts = []
    for v, en in truth.items():
        parts.append(_track_rows(v, "gps", t, en + rng.normal(0, 1.3, en.shape), 1.8))
        if v != FOLLOWER:
            parts.append(_track_rows(v, "ins", t, en + rng.normal(0, 0.5, en.shape), 0.7))
    for k, method in enumerate(FOLLOWER_METHODS):
        drift = np.cumsum(rng.normal(0, 0.05 * (len(FOLLOWER_METHODS) - k), (t.size, 2)), axis=0)
        parts.append(_track_rows(FOLLOWER, method, t, truth[FOLLOWER] + drift, 1.0 + 0.2 * k))
    return pd.concat(parts, ignore_index=True)


def _ranges(rng: np.random.Generator, n: int) -> pd.DataFrame:
    t = 1.0 + PING_S * np.arange(n)
    leader = np.array(LEADERS)[np.arange(n) % 2]
    truth = _truth(t)
    lead_en = np.where((leader == "leader1")[:, None], truth["leader1"], truth["leader2"])
    true_h = np.hypot(*(truth[FOLLOWER] - lead_en).T)
    true_m = np.hypot(true_h, 4.0)
    anomaly = np.zeros(n)
    anomaly[n // 10: n // 10 + max(2, n // 20)] = 15.0                 # a stale stretch inside training
    anomaly[int(0.7 * n): int(0.7 * n) + max(2, n // 15)] = np.linspace(5, 25, max(2, n // 15))
    measured = true_m + rng.normal(0, 3.0, n) + anomaly
    return pd.DataFrame({"t_s": t, "follower": FOLLOWER, "leader": leader, "measured_m": measured,
                         "true_m": true_m, "residual_m": measured - true_m, "leader_east_m": lead_en[:, 0],
                         "leader_north_m": lead_en[:, 1], "horizontal_m": np.sqrt(np.maximum(measured**2 - 16, 0))})


def _detections(rng: np.random.Generator, ranges: pd.DataFrame, t_a: float) -> pd.DataFrame:
    n = len(ranges)
    err = np.abs(ranges["residual_m"].to_numpy())
    label = np.where(ranges["t_s"].to_numpy() > 0, (err > 9.0).astype(int), -1)
    f1 = err + rng.normal(0, 0.5, n).clip(0)
    f2 = (f1 / 3.0) ** 2
    f3 = 9.0 * np.maximum(1.0, f2)
    parts = []
    for k, method in enumerate(DETECTORS):
        score = f2 if method == "chi_square" else err * (0.8 + 0.1 * k) + rng.normal(0, 1.0, n)
        thr = 6.63 if method == "chi_square" else 5.5 + k
        flagged = (score > thr) & (ranges["t_s"].to_numpy() > t_a)
        parts.append(pd.DataFrame({
            "t_s": ranges["t_s"], "follower": FOLLOWER, "leader": ranges["leader"], "method": method,
            "flagged": flagged, "score": score, "threshold": thr, "f1_innovation_m": f1, "f2_mahalanobis2": f2,
            "f3_r_adapted_m2": f3, "label": label, "isolated": flagged, "capped": np.zeros(n, dtype=bool)}))
    return pd.concat(parts, ignore_index=True)


def _errors(tracks: pd.DataFrame) -> pd.DataFrame:
    gps = tracks[(tracks.vehicle == FOLLOWER) & (tracks.source == "gps")].set_index("t_s")
    parts = []
    for method in FOLLOWER_METHODS:
        est = tracks[(tracks.vehicle == FOLLOWER) & (tracks.source == method)].set_index("t_s")
        err = np.hypot(est.east_m - gps.east_m, est.north_m - gps.north_m)
        parts.append(pd.DataFrame({"t_s": err.index, "follower": FOLLOWER, "method": method, "error_m": err.values}))
    return pd.concat(parts, ignore_index=True)


def _bell(x: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.abs((x - c) / a) ** (2 * b))


def _anfis_params(rng: np.random.Generator, epochs: int) -> list[dict]:
    """A premise drifting from genfis1's start, as training would move it; grid rules."""
    rules = len(list(itertools.product(range(MFS), repeat=INPUTS)))
    q = rng.normal(0, 2.0, (rules, INPUTS + 1))
    out = []
    for e in range(epochs):
        s = e / max(1, epochs - 1)
        c = np.array([[0.0 + 0.1 * s, 1.0 - 0.15 * s]] * INPUTS)
        a = np.full((INPUTS, MFS), 0.5 + 0.1 * s)
        b = np.full((INPUTS, MFS), 2.0 + 0.3 * s)
        memb = [[[float(a[d, m]), float(b[d, m]), float(c[d, m])] for m in range(MFS)] for d in range(INPUTS)]
        out.append({"membership": memb, "consequents": (q * (0.5 + 0.5 * s)).tolist(),
                    "input_min": [0.0, 0.0, 9.0], "input_max": [30.0, 100.0, 900.0]})
    return out


def _anfis(rng: np.random.Generator, det: pd.DataFrame, t_a: float,
           epochs: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    ep_rows, ex_rows = [], []
    for leader in LEADERS:
        model = f"anfis/{leader}"
        params = _anfis_params(rng, epochs)
        rmse = 4.0 * np.exp(-np.arange(epochs) / 8.0) + 1.5
        ep_rows += [{"model": model, "epoch": e, "rmse": float(rmse[e]), "params": params[e]} for e in range(epochs)]
        final = params[-1]
        abc = np.array(final["membership"])                              # (D, M, 3)
        rows = det[(det.method == "anfis") & (det.leader == leader) & (det.t_s > t_a)]
        raw = rows[["f1_innovation_m", "f2_mahalanobis2", "f3_r_adapted_m2"]].to_numpy()
        lo, hi = np.array(final["input_min"]), np.array(final["input_max"])
        x = np.clip((raw - lo) / (hi - lo), 0, 1)
        mu = _bell(x[:, :, None], abc[None, :, :, 0], abc[None, :, :, 1], abc[None, :, :, 2])
        table = np.array(list(itertools.product(range(MFS), repeat=INPUTS)))
        w = mu[:, np.arange(INPUTS)[None, :], table].prod(axis=-1)       # (n, R)
        for i, (_, r) in enumerate(rows.iterrows()):
            ex_rows.append({"t_s": r.t_s, "model": model, "inputs": x[i].tolist(), "memberships": mu[i].tolist(),
                            "firing": w[i].tolist(), "output": float(r.score), "threshold": float(r.threshold),
                            "flagged": bool(r.flagged)})
    return pd.DataFrame(ep_rows), pd.DataFrame(ex_rows)


def _kmcdf(rng: np.random.Generator, duration: float) -> pd.DataFrame:
    t = np.arange(2.2, duration, USBL_S)
    truth = _truth(t)[FOLLOWER]
    ang = np.pi / 4 + np.arange(N_NODES) * 2 * np.pi / N_NODES
    nodes = 1131.0 * np.column_stack([np.cos(ang), np.sin(ang)])
    n_fix = N_NODES + 2 * 6 + 4
    rows = []
    for i, ti in enumerate(t):
        for method in KMCDF_METHODS:
            fixes = truth[i] + rng.normal(0, 3.0, (n_fix, 2))
            bad = rng.random(n_fix) < 0.2
            fixes[bad] += rng.normal(0, 300.0, (bad.sum(), 2))
            final = fixes[~bad].mean(axis=0) if (~bad).any() else truth[i]
            rows.append({"t_s": ti, "target": FOLLOWER, "method": method, "east_m": final[0], "north_m": final[1],
                         "fixes_east_m": fixes[:, 0].tolist(), "fixes_north_m": fixes[:, 1].tolist(),
                         "fixes_cluster": np.where(bad, 2, 1).tolist(), "nodes_east_m": nodes[:, 0].tolist(),
                         "nodes_north_m": nodes[:, 1].tolist(), "delay_normal": (rng.random(N_NODES) > 0.1).tolist(),
                         "phase_normal": (rng.random(N_NODES) > 0.05).tolist()})
    return pd.DataFrame(rows)


def _events(det: pd.DataFrame, t_a: float) -> pd.DataFrame:
    flagged = det[det.flagged & (det.method == "anfis")]
    rows = [{"t_s": t_a, "level": "INFO", "text": "ANFIS training finished (2 models)"},
            {"t_s": 3.0, "level": "WARN", "text": "follower/dvl.pd0 byte 4096: bad checksum, skipped"}]
    rows += [{"t_s": r.t_s, "level": "WARN", "text": f"anfis flagged {r.leader} range (score {r.score:.1f} m)"}
             for r in flagged.itertuples()]
    return pd.DataFrame(rows).sort_values("t_s", ignore_index=True)


def synthetic_review(seed: int, n_epochs: int = 60, anfis_epochs: int = 12, run_id: str = "run-a") -> ReviewData:
    """A complete, seeded ReviewData with `n_epochs` ranging epochs (tracks at 1 Hz over the same span)."""
    rng = np.random.default_rng(seed)
    duration = PING_S * n_epochs + 2.0
    t_a = 0.4 * duration
    t = np.arange(0.0, duration, 1.0 / TRACK_HZ)
    tracks = _tracks(rng, t)
    ranges = _ranges(rng, n_epochs)
    det = _detections(rng, ranges, t_a)
    anfis_epochs_df, explain = _anfis(rng, det, t_a, anfis_epochs)
    kmcdf = _kmcdf(rng, duration)
    km_tracks = [_track_rows(FOLLOWER, m, kmcdf[kmcdf.method == m].t_s.to_numpy(),
                             kmcdf[kmcdf.method == m][["east_m", "north_m"]].to_numpy(), 3.0) for m in KMCDF_METHODS]
    return ReviewData(
        run_id=run_id, trial="synthetic", trial_start_ns=T0_NS, origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1],
        vehicles={"leader1": "leader", "leader2": "leader", FOLLOWER: "follower"},
        methods=[*FOLLOWER_METHODS, *KMCDF_METHODS],
        tracks=pd.concat([tracks, *km_tracks], ignore_index=True), ranges=ranges, detections=det,
        errors=_errors(tracks), anfis_epochs=anfis_epochs_df, anfis_explain=explain, kmcdf=kmcdf,
        events=_events(det, t_a), metrics={"run_id": run_id, "window": [t_a, duration]},
    )
