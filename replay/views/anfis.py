"""ANFIS views: membership functions and output surface per training epoch, and why each epoch was flagged.

Entities under ``P/anfis/<model>`` (P the run prefix):
- on the `anfis_epoch` sequence timeline: ``training/mf/in<d>`` (LineStrips2D, one
  strip per MF, x = normalized input, y = -grade), ``training/rmse`` (Scalars),
  ``training/surface`` (Mesh3D over inputs 1 and 2 with input 3 at its median, over the
  range the explained epochs occupy, z = output / the frame's top, clipped; triangles static);
- static: ``training/axes`` (labelled with each input's range in its own units),
  ``training/T2`` (a translucent plane at the threshold) and ``training/rmse_bars``
  (RMSE per training epoch as a bar chart, readable on any timeline);
- on `time` / `mission_s`, from the end of training: the kept model's MFs and surface again,
  ``training/epoch`` (this epoch's inputs and output on the surface, red when above T2),
  ``explain/mf/in<d>/grade`` (the epoch's input on each MF, labelled with its grade) over the
  static final curves ``explain/mf/in<d>/curves``, ``explain/firing`` (one bar per rule,
  y = -w), and ``explain/verdict`` (a TextDocument saying why it was or was not flagged).

The model math is the stack's own (seed 000, A.21-A.25: bell MFs, product
firing, normalized weighted sum of linear consequents), batched over epochs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd
import rerun as rr

from replay.stack.detectors.anfis import (
    bell,
    normalized_firing,
    rule_outputs,
    rule_table,
)
from replay.views.common import CLUSTER_COLORS, Run, floats

INPUT_NAMES = ("f1 |r| (m)", "f2 r'Pzz^-1 r", "f3 R* (m^2)")
MF_POINTS = 101
SURFACE_GRID = 21
MF_COLORS = np.array([[90, 160, 255], [255, 150, 60], [120, 220, 120], [220, 110, 220], [230, 230, 90]],
                     dtype=np.uint8)


@dataclass(frozen=True)
class ModelHistory:
    """Premise (E, D, M) a/b/c, consequents (E, R, D+1), rule table (R, D) and RMSE (E,) of one model."""

    epochs: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    consequents: np.ndarray
    rules: np.ndarray
    rmse: np.ndarray
    input_min: np.ndarray
    input_max: np.ndarray

    @property
    def best(self) -> int:
        """Index of the lowest-RMSE epoch (the kept model)."""
        r = np.where(np.isfinite(self.rmse), self.rmse, np.inf)
        return int(np.argmin(r)) if r.size else 0


def premise_of(params: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, b, c), each (D, M), from a params dict: `membership[d][m] = (a, b, c)` or separate a/b/c."""
    if "membership" in params:
        abc = np.asarray(params["membership"], dtype=float)
        return abc[..., 0], abc[..., 1], abc[..., 2]
    return (np.asarray(params["a"], dtype=float), np.asarray(params["b"], dtype=float),
            np.asarray(params["c"], dtype=float))


def history_of(rows: pd.DataFrame) -> ModelHistory | None:
    """Stack one model's epochs (rows of anfis_epochs); None when the params cannot be read."""
    rows = rows.sort_values("epoch", kind="stable")
    try:
        prem = [premise_of(p) for p in rows["params"]]
        q = np.stack([np.asarray(p["consequents"], dtype=float) for p in rows["params"]])
        a, b, c = (np.stack([x[i] for x in prem]) for i in range(3))
    except (KeyError, TypeError, ValueError, IndexError):
        return None
    first = rows["params"].iloc[0]
    d, m = a.shape[1], a.shape[2]
    if "rules" in first:
        rules = np.asarray(first["rules"], dtype=np.intp)
    else:
        structure = first.get("rule_structure") or ("grid" if q.shape[1] == m**d else "diagonal")
        rules = rule_table(d, m, structure)
    last = rows["params"].iloc[-1]
    lo = np.asarray(last.get("input_min", np.zeros(d)), dtype=float).ravel()
    hi = np.asarray(last.get("input_max", np.ones(d)), dtype=float).ravel()
    if lo.size != d or hi.size != d:
        lo, hi = np.zeros(d), np.ones(d)
    return ModelHistory(rows["epoch"].to_numpy(dtype=np.int64), a, b, c, q, rules, floats(rows, "rmse"), lo, hi)


def mf_strips(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Curves (..., M, MF_POINTS, 2) of x in [0, 1] against -grade for premises (..., M)."""
    x = np.linspace(0.0, 1.0, MF_POINTS)
    mu = bell(x, a[..., None], b[..., None], c[..., None])
    return np.stack([np.broadcast_to(x, mu.shape), -mu], axis=-1)


def surface(h: ModelHistory, third: float, grid: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Grid inputs (G*G, 3) and outputs (E, G*G) over inputs 1 and 2, input 3 held at `third`.

    `grid` (2, G) gives each input's grid values (normalised); evenly over [0, 1] by default.
    """
    g = np.linspace(0.0, 1.0, SURFACE_GRID)
    grid = np.stack([g, g]) if grid is None else np.asarray(grid, dtype=float)
    x1, x2 = np.meshgrid(grid[0], grid[1], indexing="ij")
    x = np.column_stack([x1.ravel(), x2.ravel(), np.full(x1.size, third)])[:, : h.a.shape[1]]
    _, wbar = normalized_firing(x, h.a, h.b, h.c, h.rules)                 # (E, n, R)
    return x, (wbar * rule_outputs(x, h.consequents)).sum(axis=-1)


def grid_triangles(n: int) -> np.ndarray:
    """Triangle indices (2 (n-1)^2, 3) of an n x n vertex grid laid out row-major."""
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    v = (i * n + j).ravel()
    return np.concatenate([np.column_stack([v, v + n, v + 1]), np.column_stack([v + 1, v + n, v + n + 1])]
                          ).astype(np.uint32)


def surface_colors(z: np.ndarray, threshold: float) -> np.ndarray:
    """Blue-to-green by height, red where the output exceeds the threshold."""
    lo, hi = np.nanmin(z), np.nanmax(z)
    s = (z - lo) / (hi - lo) if hi > lo else np.zeros_like(z)
    rgb = np.stack([40 + 0 * s, 80 + 150 * s, 230 - 150 * s], axis=-1)
    if np.isfinite(threshold):
        rgb = np.where((z > threshold)[..., None], [235, 70, 50], rgb)
    return np.nan_to_num(rgb).astype(np.uint8)


def log_anfis(rec: rr.RecordingStream, run: Run) -> None:
    """Training history and per-epoch explanations of every ANFIS model of a run."""
    histories = {str(k[0]): history_of(rows) for k, rows in run.groups(run.review.anfis_epochs, ["model"])}
    explain = {str(k[0]): rows for k, rows in run.groups(run.review.anfis_explain, ["model"])}
    for model, h in histories.items():
        if h is not None:
            _log_training(rec, run, model, h, explain.get(model))
    for model, rows in explain.items():
        _log_explain(rec, run, model, rows, histories.get(model))


def _third_input(rows: pd.DataFrame | None) -> float:
    if rows is None or rows.empty:
        return 0.5
    x = np.array([np.asarray(v, dtype=float)[2] if len(v) > 2 else np.nan for v in rows["inputs"]])
    return float(np.nanmedian(x)) if np.isfinite(x).any() else 0.5


GRID_PROBS = np.linspace(0.0, 0.99, SURFACE_GRID)
"""The surface's grid lines sit at these quantiles of the epochs' inputs (the top 1 % left out)."""


def data_grid(rows: pd.DataFrame | None) -> np.ndarray:
    """(2, G) grid values of normalised inputs 1 and 2: their quantiles over the explained epochs.

    The inputs are heavy-tailed (the median |r| is a few per cent of its range): an even grid over
    their range puts nearly every grid point where no epoch ever was. On quantiles, each grid step
    holds the same share of epochs, so the surface shows what the model does where the data are.
    """
    even = np.stack([np.linspace(0.0, 1.0, SURFACE_GRID)] * 2)
    if rows is None or rows.empty:
        return even
    try:
        x = np.stack([np.asarray(v, dtype=float)[:2] for v in rows["inputs"]])
    except ValueError:
        return even
    out = even.copy()
    for d in range(2):
        v = x[:, d][np.isfinite(x[:, d])]
        if v.size >= 2:
            q = np.quantile(v, GRID_PROBS)
            out[d] = q + 1e-9 * np.arange(q.size)          # strictly increasing, for interpolation
    return out


def _training_end(explain: pd.DataFrame | None) -> float:
    """Where the trained model appears on `time`: the first explained epoch (else the trial start)."""
    t = floats(explain, "t_s") if explain is not None else np.zeros(0)
    t = t[np.isfinite(t)]
    return float(t.min()) if t.size else 0.0


@dataclass(frozen=True)
class SurfaceFrame:
    """How the surface sits in its 3D view: x, y = the share of epochs below each input (its grid's
    quantile, 0 to 0.99), z = output / z_top."""

    grid: np.ndarray
    z_top: float
    threshold: float

    def xyz(self, x: np.ndarray, out: np.ndarray) -> np.ndarray:
        """View coordinates (..., 3) of normalised inputs (..., >=2) and outputs (...), z clipped to [0, 1]."""
        xy = np.stack([np.interp(x[..., d], self.grid[d], GRID_PROBS) for d in range(2)], axis=-1)
        return np.concatenate([xy, np.clip(out / self.z_top, -0.05, 1.0)[..., None]], axis=-1)


def surface_frame(grid: np.ndarray, explain: pd.DataFrame | None, thr: float) -> SurfaceFrame:
    """z extent: twice T2 or the 95th percentile of the epochs' outputs, whichever is larger."""
    out = floats(explain, "output") if explain is not None else np.zeros(0)
    out = out[np.isfinite(out)]
    top = max(2.0 * thr if np.isfinite(thr) else 0.0, float(np.quantile(out, 0.95)) if out.size else 0.0)
    return SurfaceFrame(grid, top if top > 0 else 1.0, thr)


def _log_training(rec: rr.RecordingStream, run: Run, model: str, h: ModelHistory,
                  explain: pd.DataFrame | None) -> None:
    """Every epoch on `anfis_epoch`; the kept (best) epoch once more on `time`, from the end of training."""
    all_epochs = np.arange(h.a.shape[0])
    grid = data_grid(explain)
    x, out = surface(h, _third_input(explain), grid)
    thr = float(floats(explain, "threshold")[0]) if explain is not None and not explain.empty else float("nan")
    frame = surface_frame(grid, explain, thr)
    for sel, index in ((all_epochs, [rr.TimeColumn("anfis_epoch", sequence=h.epochs)]),
                       (np.array([h.best]), run.times(np.array([_training_end(explain)])))):
        _log_mfs(rec, run, model, h, sel, index)
        if h.a.shape[1] >= 2:
            _log_surface(rec, run, model, x, out[sel], frame, index)
    rec.log(run.path("anfis", model, "training", "rmse"), rr.SeriesLines(names=run.name(f"{model} RMSE")),
            static=True)
    rec.send_columns(run.path("anfis", model, "training", "rmse"), indexes=[rr.TimeColumn("anfis_epoch",
                                                                                          sequence=h.epochs)],
                     columns=rr.Scalars.columns(scalars=h.rmse))
    # the same curve as a static bar chart: readable on the default timeline, where training is one instant
    rec.log(run.path("anfis", model, "training", "rmse_bars"),
            rr.BarChart(np.nan_to_num(h.rmse), abscissa=h.epochs.astype(float), color=(90, 160, 255)), static=True)
    if h.a.shape[1] >= 2:
        _log_surface_frame(rec, run, model, h, frame, explain)


def _log_surface_frame(rec: rr.RecordingStream, run: Run, model: str, h: ModelHistory, frame: SurfaceFrame,
                       explain: pd.DataFrame | None) -> None:
    """Axes labelled in the inputs' own units and range, and T2 as a translucent plane."""
    lo, hi = h.input_min, h.input_max
    real = lo[:2, None] + frame.grid * (hi[:2, None] - lo[:2, None])          # grid values in the inputs' units
    mid = SURFACE_GRID // 2
    labels = [f"f1 by rank: median {real[0, mid]:.3g} m, 99 % {real[0, -1]:.3g} m",
              f"f2 by rank: median {real[1, mid]:.3g}, 99 % {real[1, -1]:.3g}",
              f"output (m), top {frame.z_top:.3g}"]
    axes = [np.array([[0, 0, 0], [1, 0, 0]]), np.array([[0, 0, 0], [0, 1, 0]]), np.array([[0, 0, 0], [0, 0, 1]])]
    rec.log(run.path("anfis", model, "training", "axes"),
            rr.LineStrips3D(axes, labels=labels, colors=[(128, 128, 128)]), static=True)
    if np.isfinite(frame.threshold):
        z = frame.threshold / frame.z_top
        rec.log(run.path("anfis", model, "training", "T2"),
                rr.Mesh3D(vertex_positions=[[0, 0, z], [0.99, 0, z], [0.99, 0.99, z], [0, 0.99, z]],
                          triangle_indices=[[0, 1, 2], [0, 2, 3]], albedo_factor=(235, 70, 50, 70)), static=True)
        rec.log(run.path("anfis", model, "training", "T2_label"),
                rr.Points3D([[0.99, 0.99, z]], labels=[f"T2 = {frame.threshold:.2f} m"], colors=[(235, 70, 50)],
                            radii=rr.Radius.ui_points(3.0)), static=True)
    if explain is not None and not explain.empty:
        try:
            xin = np.stack([np.asarray(v, dtype=float) for v in explain["inputs"]])
        except ValueError:
            return
        out = floats(explain, "output")
        flagged = out > floats(explain, "threshold")
        pos = frame.xyz(xin, out)
        n = len(explain)
        text = [f"this epoch: {o:.2f} m" + (" > T2" if f else "") for o, f in zip(out, flagged, strict=True)]
        cols = rr.Points3D.columns(positions=pos, labels=text,
                                   colors=np.where(flagged[:, None], [235, 70, 50], [255, 255, 255]).astype(np.uint8),
                                   radii=np.full(n, rr.Radius.ui_points(7.0), dtype=np.float32))
        rec.send_columns(run.path("anfis", model, "training", "epoch"), indexes=run.times(explain["t_s"]),
                         columns=cols)


def _log_mfs(rec: rr.RecordingStream, run: Run, model: str, h: ModelHistory, sel: np.ndarray,
             index: list[rr.TimeColumn]) -> None:
    e, d, m = sel.size, h.a.shape[1], h.a.shape[2]
    strips = mf_strips(h.a[sel], h.b[sel], h.c[sel])                     # (e, D, M, P, 2)
    for i in range(d):
        cols = rr.LineStrips2D.columns(strips=np.ascontiguousarray(strips[:, i].reshape(e * m, MF_POINTS, 2)),
                                       colors=np.tile(MF_COLORS[np.arange(m) % len(MF_COLORS)], (e, 1)),
                                       labels=np.tile([f"MF{k + 1}" for k in range(m)], e))
        rec.send_columns(run.path("anfis", model, "training", "mf", f"in{i + 1}"), indexes=index,
                         columns=cols.partition(np.full(e, m)))


def _log_surface(rec: rr.RecordingStream, run: Run, model: str, x: np.ndarray, out: np.ndarray,
                 frame: SurfaceFrame, index: list[rr.TimeColumn]) -> None:
    e, n = out.shape
    verts = frame.xyz(np.broadcast_to(x[None, :, :], (e, *x.shape)), out)
    path = run.path("anfis", model, "training", "surface")
    rec.log(path, rr.Mesh3D.from_fields(triangle_indices=grid_triangles(SURFACE_GRID)), static=True)
    cols = rr.Mesh3D.columns(vertex_positions=verts.reshape(-1, 3),
                             vertex_colors=surface_colors(np.clip(out, None, frame.z_top),
                                                          frame.threshold).reshape(-1, 3))
    rec.send_columns(path, indexes=index, columns=cols.partition(np.full(e, n)))


def _rule_names(rules: np.ndarray, m: int) -> list[str]:
    words = {2: ("low", "high"), 3: ("low", "mid", "high")}.get(m, tuple(f"MF{k + 1}" for k in range(m)))
    return [", ".join(f"f{d + 1} {words[k]}" for d, k in enumerate(r)) for r in rules]


def _log_explain(rec: rr.RecordingStream, run: Run, model: str, rows: pd.DataFrame,
                 h: ModelHistory | None) -> None:
    try:
        x = np.stack([np.asarray(v, dtype=float) for v in rows["inputs"]])          # (n, D)
        mu = np.stack([np.asarray(v, dtype=float) for v in rows["memberships"]])    # (n, D, M)
        w = np.stack([np.asarray(v, dtype=float) for v in rows["firing"]])          # (n, R)
    except (KeyError, ValueError):
        return
    n, d, m = mu.shape
    times = run.times(rows["t_s"])
    for i in range(d):
        base = run.path("anfis", model, "explain", "mf", f"in{i + 1}")
        if h is not None:
            k = h.best
            rec.log(base + "/curves", rr.LineStrips2D(list(mf_strips(h.a[k, i], h.b[k, i], h.c[k, i])),
                                                      colors=MF_COLORS[np.arange(m) % len(MF_COLORS)]), static=True)
        pos = np.stack([np.repeat(x[:, i], m), -mu[:, i].ravel()], axis=-1)
        labels = (pd.Series(np.tile([f"MF{j + 1} " for j in range(m)], n)) + pd.Series(mu[:, i].ravel()).round(2)
                  .astype(str)).to_numpy()
        cols = rr.Points2D.columns(positions=pos, labels=labels, colors=np.tile(MF_COLORS[np.arange(m) % 5], (n, 1)),
                                   radii=np.full(n * m, rr.Radius.ui_points(5.0), dtype=np.float32))
        rec.send_columns(base + "/grade", indexes=times, columns=cols.partition(np.full(n, m)))
    _log_firing(rec, run, model, w, times)
    rules = h.rules if h is not None and h.rules.shape[0] == w.shape[1] else None
    names = _rule_names(rules, m) if rules is not None else [f"rule {r + 1}" for r in range(w.shape[1])]
    rec.send_columns(run.path("anfis", model, "explain", "verdict"), indexes=times,
                     columns=rr.TextDocument.columns(text=verdicts(rows, w, names),
                                                     media_type=["text/markdown"] * n))


def _log_firing(rec: rr.RecordingStream, run: Run, model: str, w: np.ndarray, times: list[rr.TimeColumn]) -> None:
    n, r = w.shape
    xs = np.broadcast_to(np.arange(r, dtype=float) / max(r - 1, 1), (n, r))
    bars = np.stack([np.stack([xs, np.zeros_like(w)], -1), np.stack([xs, -w], -1)], axis=2)     # (n, R, 2, 2)
    top = (w == w.max(axis=1, keepdims=True)).ravel()
    colors = np.where(top[:, None], CLUSTER_COLORS[1], [120, 120, 160]).astype(np.uint8)
    labels = (pd.Series(np.tile([f"R{k + 1} " for k in range(r)], n)) + pd.Series(w.ravel()).round(2).astype(str))
    cols = rr.LineStrips2D.columns(strips=np.ascontiguousarray(bars.reshape(n * r, 2, 2)), colors=colors,
                                   labels=labels.to_numpy(),
                                   radii=np.full(n * r, 0.3 / max(r, 1), dtype=np.float32))
    rec.send_columns(run.path("anfis", model, "explain", "firing"), indexes=times,
                     columns=cols.partition(np.full(n, r)))


def verdicts(rows: pd.DataFrame, w: np.ndarray, rule_names: list[str]) -> list[str]:
    """One markdown paragraph per epoch: output against T2, the verdict, and the strongest rules."""
    out, thr = floats(rows, "output"), floats(rows, "threshold")
    flagged = rows["flagged"].to_numpy(dtype=bool) if "flagged" in rows else out > thr
    total = np.maximum(w.sum(axis=1), 1e-300)
    order = np.argsort(-w, axis=1)[:, :2]
    text = []
    for i, t in enumerate(floats(rows, "t_s")):
        cmp, word = (">", "**flagged**") if flagged[i] else ("<=", "not flagged")
        top = "; ".join(f"R{k + 1} ({rule_names[k]}) w={w[i, k]:.2f}, {100 * w[i, k] / total[i]:.0f} %"
                        for k in order[i])
        text.append(f"t = {t:.1f} s: output {out[i]:.2f} m {cmp} T2 {thr[i]:.2f} m, {word}.\n\n"
                    f"Strongest rules: {top}.")
    return text

