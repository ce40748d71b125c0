"""ANFIS views: membership functions and output surface per training epoch, and why each epoch was flagged.

One view per ANFIS model: every method of the method table with an ANFIS model (`anfis_models`:
anfis, anfis_aqpso, anfis_compensation, anfis_hybrid) that ran, per leader. A model is named
``<method>/<leader>`` in the review's tables (``<method>/<follower>/<leader>`` with several followers).
Entities under ``P/anfis/<method>/<leader>`` (P the run prefix):
- static: ``note`` (a TextDocument: method, leader, inputs, MFs per input, rules, training, threshold)
  and ``training/mf/in<d>/axis`` (tick marks labelled with the input's real values, and the grade);
- on the `anfis_epoch` sequence timeline, at TRAINING_FRAMES epochs and the kept one:
  ``training/mf/in<d>`` (LineStrips2D, one strip per MF, x = normalized input, y = -grade) and
  ``training/surface`` (Mesh3D over inputs 1 and 2 with the others at their median, over the
  range the explained epochs occupy, z = output / the frame's top, clipped; triangles static);
  at every epoch ``training/rmse`` (Scalars);
- static: ``training/axes`` (labelled with each input's range in its own units),
  ``training/T2`` (a translucent plane at the threshold) and ``training/rmse_bars``
  (RMSE per training epoch as a bar chart, readable on any timeline);
- on `time` / `mission_s`, from the end of training: the kept model's MFs and surface again,
  ``training/epoch`` (this epoch's inputs and output on the surface, red when above T2),
  ``explain/mf/in<d>/grade`` (the epoch's input on each MF, then its grades read out one line per MF
  at the top of the plot) over the
  static final curves ``explain/mf/in<d>/curves``, ``explain/firing`` (one bar per rule,
  y = -w, the strongest labelled with its weight, over the static ``explain/firing_axis``: rule
  numbers and the w scale), and ``explain/verdict`` (a TextDocument saying why it was or was not flagged).

The model math is the stack's own (seed 000, A.21-A.25: bell MFs, product
firing, normalized weighted sum of linear consequents), batched over epochs.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
import pandas as pd
import rerun as rr

from replay.stack.detectors.anfis import (
    bell,
    normalized_firing,
    rule_outputs,
    rule_table,
)
from replay.stack.methods import METHOD_TABLE, anfis_models
from replay.views.common import CLUSTER_COLORS, Run, floats

PAPER_INPUTS = ("f1", "f2", "f3")
# an input's title on its axis, with its unit, short enough for a narrow view's title (about 15 characters);
# anfis_hybrid's inputs are magnitudes, its f2 a square root
INPUT_TITLES = {"f1": "f1 |r| (m)", "f2": "f2 r'P^-1 r", "f3": "f3 R* (m^2)", "repeat_count": "repeats",
                "dr_residual_m": "|DR res.| (m)", "leader_consistency_m": "|consist.| (m)",
                "usbl_residual_m": "|USBL res.| (m)", "lag_residual_m": "|lag res.| (m)",
                "drift_residual_m": "|drift res.| (m)", "drift_cusum_m": "drift CUSUM (m)",
                "exclusion_residual_m": "|excl. res.| (m)", "drift_z": "|drift_z| (sd)",
                "exclusion_z": "|excl_z| (sd)"}
TRAINERS = {"hybrid": "hybrid learning (LSE + gradient)", "aqpso_ga": "AQPSO-GA"}
MF_TICKS = np.linspace(0.0, 1.0, 5)
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


def model_parts(model: str) -> tuple[str, str]:
    """(method, leader) of a model's name "<method>/<leader>"; a bare leader is paper A's `anfis`."""
    method, sep, leader = str(model).partition("/")
    return (method, leader) if sep else ("anfis", str(model))


def model_order(models: set[str]) -> list[str]:
    """Model names in the method table's order (anfis_models), then by leader; unknown methods last."""
    order = {m: i for i, m in enumerate(anfis_models())}
    return sorted(models, key=lambda k: (order.get(model_parts(k)[0], len(order)), model_parts(k)))


def model_path(run: Run, model: str, *parts: str) -> str:
    """An entity path under a model's root, ``P/anfis/<method>/<leader>``."""
    return run.path("anfis", *model_parts(model), *parts)


def input_title(name: str, model_method: str = "") -> str:
    """An input's axis title; anfis_hybrid takes the square root of f2."""
    if name == "f2" and model_method == "anfis_hybrid":
        return "sqrt f2"
    return INPUT_TITLES.get(name, name)


def input_short(title: str) -> str:
    """An input's title without its unit or formula: "f1", "|drift res.|"."""
    return title.split(" ")[0] if title[:1] == "f" and title[1:2].isdigit() else title.rsplit(" (", 1)[0]


def model_inputs(rows: pd.DataFrame | None) -> tuple[str, ...]:
    """The feature names a model reads (from its anfis_epochs params; paper A's three when not given)."""
    if rows is None or rows.empty or "params" not in rows:
        return PAPER_INPUTS
    params = rows["params"].iloc[0]
    names = params.get("inputs") if isinstance(params, dict) else None
    return tuple(str(n) for n in names) if isinstance(names, (list, tuple)) and names else PAPER_INPUTS


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
    params = rows["params"].tolist()
    try:
        if all("membership" in p for p in params):        # the stack's own form: every epoch in one array
            abc = np.asarray([p["membership"] for p in params], dtype=float)
            a, b, c = abc[..., 0], abc[..., 1], abc[..., 2]
        else:
            prem = [premise_of(p) for p in params]
            a, b, c = (np.stack([x[i] for x in prem]) for i in range(3))
        q = np.asarray([p["consequents"] for p in params], dtype=float)
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


def surface(h: ModelHistory, third: float, grid: np.ndarray | None = None,
            epochs: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Grid inputs (G*G, D) and outputs (E, G*G) over inputs 1 and 2, every other input held at `third`.

    `grid` (2, G) gives each input's grid values (normalised); evenly over [0, 1] by default. `epochs`
    (indices) limits the outputs to those epochs (default: every epoch).
    """
    g = np.linspace(0.0, 1.0, SURFACE_GRID)
    grid = np.stack([g, g]) if grid is None else np.asarray(grid, dtype=float)
    x1, x2 = np.meshgrid(grid[0], grid[1], indexing="ij")
    d = h.a.shape[1]
    x = np.column_stack([x1.ravel(), x2.ravel(), *([np.full(x1.size, third)] * max(d - 2, 0))])[:, :d]
    sel = slice(None) if epochs is None else np.asarray(epochs, dtype=np.intp)
    _, wbar = normalized_firing(x, h.a[sel], h.b[sel], h.c[sel], h.rules)      # (E, n, R)
    return x, (wbar * rule_outputs(x, h.consequents[sel])).sum(axis=-1)


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
    """Training history, model note, MF axes and per-epoch explanations of every ANFIS model of a run."""
    epochs = {str(k[0]): rows for k, rows in run.groups(run.review.anfis_epochs, ["model"])}
    histories = {model: history_of(rows) for model, rows in epochs.items()}
    explain = {str(k[0]): rows for k, rows in run.groups(run.review.anfis_explain, ["model"])}
    for model, h in histories.items():
        if h is not None:
            _log_training(rec, run, model, h, explain.get(model), model_inputs(epochs[model]))
            _log_mf_axes(rec, run, model, h, model_inputs(epochs[model]))
        rec.log(model_path(run, model, "note"), rr.TextDocument(model_note(model, epochs[model], h,
                                                                            explain.get(model)),
                                                                 media_type="text/markdown"), static=True)
    for model, rows in explain.items():
        h = histories.get(model)
        _log_explain(rec, run, model, rows, h, model_inputs(epochs.get(model)))


def model_note(model: str, rows: pd.DataFrame, h: ModelHistory | None, explain: pd.DataFrame | None) -> str:
    """What a model is, in a few lines: method and leader, inputs with their range, MFs, rules, training, T2."""
    method, leader = model_parts(model)
    params = rows["params"].iloc[-1] if not rows.empty and isinstance(rows["params"].iloc[-1], dict) else {}
    entry = METHOD_TABLE.get(method)
    lines = [f"**{method}** on **{leader}**" + (f": {entry.label}" if entry else "")]
    if h is None:
        return "\n\n".join([*lines, "(its parameters could not be read)"])
    m, r = h.a.shape[2], h.rules.shape[0]
    names = model_inputs(rows)
    ranges = "; ".join(f"{input_title(n, method)} {tick(lo, hi - lo)} to {tick(hi, hi - lo)}"
                       for n, lo, hi in zip(names, h.input_min, h.input_max, strict=False))
    trainer = str(params.get("trainer", "hybrid"))
    steps = "iterations" if trainer == "aqpso_ga" else "epochs"
    target = "the signed range error" if params.get("compensation") else "|range error|"
    samples = params.get("training_samples")
    kept = f"kept {steps[:-1]} {int(h.epochs[h.best])} of {h.epochs.size}, RMSE {h.rmse[h.best]:.3g} m"
    lines += [f"- inputs (training range): {ranges}",
              f"- {m} bell MFs each, {r} rules ({params.get('rule_structure', 'grid')}), linear consequents",
              f"- {TRAINERS.get(trainer, trainer)} on {target}" + (f", {samples} epochs" if samples else "")
              + f"; {kept}"]
    thr = floats(explain, "threshold") if explain is not None else np.zeros(0)
    thr = thr[np.isfinite(thr)]
    if thr.size:
        lines.append(f"- flags an epoch whose output exceeds T2 = {thr[0]:.3g} m")
    return "\n".join(lines)


def tick(v: float, span: float) -> str:
    """A short tick label: 3 significant digits, no exponent from 0.001 to 99,999, 0 for a value near 0."""
    if abs(v) < 1e-3 * abs(span) or v == 0:
        return "0"
    if 1e-3 <= abs(v) < 1e5:
        return f"{v:.0f}" if abs(v) >= 100 else f"{v:.3g}"
    return f"{v:.2g}"


def axis_labels(lo: float, hi: float) -> list[str]:
    """Tick labels of a normalised axis at MF_TICKS, in the input's own units."""
    return [tick(float(v), hi - lo) for v in lo + MF_TICKS * (hi - lo)]


def _log_mf_axes(rec: rr.RecordingStream, run: Run, model: str, h: ModelHistory, names: tuple[str, ...]) -> None:
    """Under each MF plot: tick marks at MF_TICKS labelled with the input's real values (``axis/values``: the
    first MF_TICKS labels), and the grade scale beside it (the last three)."""
    d = h.a.shape[1]
    grey = (150, 150, 150)
    spots = np.vstack([np.column_stack([MF_TICKS, np.full(MF_TICKS.size, 0.07)]), [[-0.06, 0.0], [-0.06, -0.5],
                                                                                  [-0.06, -1.0]]])
    for i in range(d):
        lo = float(h.input_min[i]) if i < h.input_min.size else 0.0
        hi = float(h.input_max[i]) if i < h.input_max.size else 1.0
        base = model_path(run, model, "training", "mf", f"in{i + 1}", "axis")
        rec.log(base, _mf_axis_lines(), static=True)
        rec.log(base + "/values", rr.Points2D(spots, labels=[*axis_labels(lo, hi), "0", "0.5", "1"], colors=[grey],
                                              radii=rr.Radius.ui_points(0.5)), static=True)


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


TRAINING_FRAMES = 11
"""The MFs and the output surface are drawn at this many training epochs, evenly spread, and at the kept one:
every epoch of all eight models of a replay would cost more than every other view of the recording."""


def training_frames(h: ModelHistory) -> np.ndarray:
    """Indices of the epochs drawn on `anfis_epoch`: TRAINING_FRAMES evenly from first to last, and the kept one."""
    e = h.a.shape[0]
    return np.union1d(np.round(np.linspace(0, e - 1, min(TRAINING_FRAMES, e))).astype(np.intp), [h.best])


def _log_training(rec: rr.RecordingStream, run: Run, model: str, h: ModelHistory,
                  explain: pd.DataFrame | None, names: tuple[str, ...] = PAPER_INPUTS) -> None:
    """MFs and surface at TRAINING_FRAMES epochs on `anfis_epoch` (the RMSE at every epoch); the kept (best)
    epoch once more on `time`, from the end of training."""
    shown = training_frames(h)
    grid = data_grid(explain)
    x, out = surface(h, _third_input(explain), grid, shown)
    thr = float(floats(explain, "threshold")[0]) if explain is not None and not explain.empty else float("nan")
    frame = surface_frame(grid, explain, thr)
    best = int(np.searchsorted(shown, h.best))
    if h.a.shape[1] >= 2:
        rec.log(model_path(run, model, "training", "surface"), _surface_triangles(), static=True)
    for sel, rows, index in ((shown, np.arange(shown.size), [rr.TimeColumn("anfis_epoch", sequence=h.epochs[shown])]),
                             (np.array([h.best]), np.array([best]), run.times(np.array([_training_end(explain)])))):
        _log_mfs(rec, run, model, h, sel, index)
        if h.a.shape[1] >= 2:
            _log_surface(rec, run, model, x, out[rows], frame, index)
    rec.log(model_path(run, model, "training", "rmse"), rr.SeriesLines(names=run.name(f"{model} RMSE")),
            static=True)
    rec.send_columns(model_path(run, model, "training", "rmse"), indexes=[rr.TimeColumn("anfis_epoch",
                                                                                          sequence=h.epochs)],
                     columns=rr.Scalars.columns(scalars=h.rmse))
    # the same curve as a static bar chart: readable on the default timeline, where training is one instant
    rec.log(model_path(run, model, "training", "rmse_bars"),
            rr.BarChart(np.nan_to_num(h.rmse), abscissa=h.epochs.astype(float), color=(90, 160, 255)), static=True)
    if h.a.shape[1] >= 2:
        _log_surface_frame(rec, run, model, h, frame, explain, names)


def _log_surface_frame(rec: rr.RecordingStream, run: Run, model: str, h: ModelHistory, frame: SurfaceFrame,
                       explain: pd.DataFrame | None, names: tuple[str, ...] = PAPER_INPUTS) -> None:
    """Axes labelled in the inputs' own units and range, and T2 as a translucent plane."""
    lo, hi = h.input_min, h.input_max
    real = lo[:2, None] + frame.grid * (hi[:2, None] - lo[:2, None])          # grid values in the inputs' units
    mid = SURFACE_GRID // 2
    titles = [input_title(n, model_parts(model)[0]) for n in names]
    span = hi[:2] - lo[:2]
    labels = [f"{titles[d]} by rank: median {tick(real[d, mid], span[d])}, 99 % {tick(real[d, -1], span[d])}"
              for d in range(2)] + [f"output (m), top {frame.z_top:.3g}"]
    axes = [np.array([[0, 0, 0], [1, 0, 0]]), np.array([[0, 0, 0], [0, 1, 0]]), np.array([[0, 0, 0], [0, 0, 1]])]
    rec.log(model_path(run, model, "training", "axes"),
            rr.LineStrips3D(axes, labels=labels, colors=[(128, 128, 128)]), static=True)
    if np.isfinite(frame.threshold):
        z = frame.threshold / frame.z_top
        rec.log(model_path(run, model, "training", "T2"),
                rr.Mesh3D(vertex_positions=[[0, 0, z], [0.99, 0, z], [0.99, 0.99, z], [0, 0.99, z]],
                          triangle_indices=[[0, 1, 2], [0, 2, 3]], albedo_factor=(235, 70, 50, 70)), static=True)
        rec.log(model_path(run, model, "training", "T2_label"),
                # on the corner nearest the camera: the far one sits behind the axes' labels
                rr.Points3D([[0.99, 0.0, z]], labels=[f"T2 = {frame.threshold:.2f} m"], colors=[(235, 70, 50)],
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
        rec.send_columns(model_path(run, model, "training", "epoch"), indexes=run.times(explain["t_s"]),
                         columns=cols)


def _log_mfs(rec: rr.RecordingStream, run: Run, model: str, h: ModelHistory, sel: np.ndarray,
             index: list[rr.TimeColumn]) -> None:
    e, d, m = sel.size, h.a.shape[1], h.a.shape[2]
    strips = mf_strips(h.a[sel], h.b[sel], h.c[sel])                     # (e, D, M, P, 2)
    for i in range(d):
        cols = rr.LineStrips2D.columns(strips=np.ascontiguousarray(strips[:, i].reshape(e * m, MF_POINTS, 2)),
                                       colors=np.tile(MF_COLORS[np.arange(m) % len(MF_COLORS)], (e, 1)),
                                       labels=np.tile([f"MF{k + 1}" for k in range(m)], e))
        rec.send_columns(model_path(run, model, "training", "mf", f"in{i + 1}"), indexes=index,
                         columns=cols.partition(np.full(e, m)))


def _log_surface(rec: rr.RecordingStream, run: Run, model: str, x: np.ndarray, out: np.ndarray,
                 frame: SurfaceFrame, index: list[rr.TimeColumn]) -> None:
    e, n = out.shape
    verts = frame.xyz(np.broadcast_to(x[None, :, :], (e, *x.shape)), out)
    path = model_path(run, model, "training", "surface")
    cols = rr.Mesh3D.columns(vertex_positions=verts.reshape(-1, 3),
                             vertex_colors=surface_colors(np.clip(out, None, frame.z_top),
                                                          frame.threshold).reshape(-1, 3))
    rec.send_columns(path, indexes=index, columns=cols.partition(np.full(e, n)))


@cache
def _surface_triangles() -> rr.Mesh3D:
    """The surface's triangles (the same grid for every model and frame), built once."""
    return rr.Mesh3D.from_fields(triangle_indices=grid_triangles(SURFACE_GRID))


@cache
def _mf_axis_lines() -> rr.LineStrips2D:
    """Under an MF plot: the input axis, its tick marks at MF_TICKS and the grade scale's (the same for every plot)."""
    lines = [np.array([[0.0, 0.0], [1.0, 0.0]])] + [np.array([[x, 0.0], [x, 0.04]]) for x in MF_TICKS] \
        + [np.array([[0.0, -g], [-0.03, -g]]) for g in (0.0, 0.5, 1.0)]
    return rr.LineStrips2D(lines, colors=[(150, 150, 150)])


@cache
def _firing_axis_lines() -> rr.LineStrips2D:
    """The firing plot's axis and its grid lines at w = 0.5 and 1 (the same for every model)."""
    return rr.LineStrips2D([np.array([[-0.05, 0.0], [1.05, 0.0]])]
                           + [np.array([[-0.12, -g], [1.05, -g]]) for g in (0.5, 1.0)],
                           colors=[(150, 150, 150), (70, 70, 70), (70, 70, 70)])


def _rule_names(rules: np.ndarray, m: int, names: tuple[str, ...] = PAPER_INPUTS) -> list[str]:
    """Each rule's premise in words ("f1 low, f2 high, ..."), inputs by their feature names."""
    words = {2: ("low", "high"), 3: ("low", "mid", "high")}.get(m, tuple(f"MF{k + 1}" for k in range(m)))
    return [", ".join(f"{names[d] if d < len(names) else f'x{d + 1}'} {words[k]}" for d, k in enumerate(r))
            for r in rules]


READOUT_STEP = 0.16
"""Vertical spacing of the grade readout's lines, in grade units (a label's height in the MF plots)."""


def _log_explain(rec: rr.RecordingStream, run: Run, model: str, rows: pd.DataFrame,
                 h: ModelHistory | None, names: tuple[str, ...] = PAPER_INPUTS) -> None:
    try:
        x = np.array(rows["inputs"].tolist(), dtype=float)              # (n, D)
        mu = np.array(rows["memberships"].tolist(), dtype=float)        # (n, D, M)
        w = np.array(rows["firing"].tolist(), dtype=float)              # (n, R)
    except (KeyError, ValueError):
        return
    if x.ndim != 2 or mu.ndim != 3 or w.ndim != 2:
        return
    n, d, m = mu.shape
    times = run.times(rows["t_s"])
    for i in range(d):
        base = model_path(run, model, "explain", "mf", f"in{i + 1}")
        if h is not None:
            k = h.best
            rec.log(base + "/curves", rr.LineStrips2D(list(mf_strips(h.a[k, i], h.b[k, i], h.c[k, i])),
                                                      colors=MF_COLORS[np.arange(m) % len(MF_COLORS)]), static=True)
        # per epoch, the input on each MF (m markers), then the grades read out in a column of their own at the
        # top (m labels; at the markers they would overlap where two MFs cross): one entity, 2 m points a row
        marks = np.stack([np.repeat(x[:, i], m), -mu[:, i].ravel()], axis=-1).reshape(n, m, 2)
        spot = np.broadcast_to(np.column_stack([np.full(m, 0.5), -1.02 + READOUT_STEP * np.arange(m)]), (n, m, 2))
        pos = np.concatenate([marks, spot], axis=1).reshape(-1, 2)
        grades = mu[:, i]
        labels = [""] * m + [f"MF{j + 1} " for j in range(m)]
        text = [lab + (f"{g[j - m]:.2f}" if j >= m else "") for g in grades.tolist() for j, lab in enumerate(labels)]
        colors = np.tile(MF_COLORS[np.arange(m) % len(MF_COLORS)], (2 * n, 1))
        radii = np.tile(np.r_[np.full(m, rr.Radius.ui_points(5.0)), np.full(m, rr.Radius.ui_points(0.5))], n)
        cols = rr.Points2D.columns(positions=pos, labels=text, colors=colors, radii=radii.astype(np.float32))
        rec.send_columns(base + "/grade", indexes=times, columns=cols.partition(np.full(n, 2 * m)))
    _log_firing(rec, run, model, w, times)
    _log_firing_axis(rec, run, model, w.shape[1])
    rules = h.rules if h is not None and h.rules.shape[0] == w.shape[1] else None
    short = tuple(input_short(input_title(nm, model_parts(model)[0])) for nm in names)
    rule_words = _rule_names(rules, m, short) if rules is not None else [f"rule {r + 1}" for r in range(w.shape[1])]
    real = None
    if h is not None and h.input_min.size == d:
        real = h.input_min + x * (h.input_max - h.input_min)
    titles = [input_title(nm, model_parts(model)[0]) for nm in names[:d]]
    rec.send_columns(model_path(run, model, "explain", "verdict"), indexes=times,
                     columns=rr.TextDocument.columns(text=verdicts(rows, w, rule_words, real, titles),
                                                     media_type=["text/markdown"] * n))


def rule_x(r: int) -> np.ndarray:
    """Where each of r rules' bars stands on the firing plot's [0, 1] axis."""
    return np.arange(r, dtype=float) / max(r - 1, 1)


def _log_firing(rec: rr.RecordingStream, run: Run, model: str, w: np.ndarray, times: list[rr.TimeColumn]) -> None:
    """One bar per rule (y = -w); only the strongest bar carries its weight (several would overlap)."""
    n, r = w.shape
    xs = np.broadcast_to(rule_x(r), (n, r))
    bars = np.stack([np.stack([xs, np.zeros_like(w)], -1), np.stack([xs, -w], -1)], axis=2)     # (n, R, 2, 2)
    top = (np.arange(r)[None, :] == np.argmax(w, axis=1)[:, None]).ravel()
    colors = np.where(top[:, None], CLUSTER_COLORS[1], [120, 120, 160]).astype(np.uint8)
    cols = rr.LineStrips2D.columns(strips=np.ascontiguousarray(bars.reshape(n * r, 2, 2)), colors=colors,
                                   radii=np.full(n * r, 0.3 / max(r, 1), dtype=np.float32))
    rec.send_columns(model_path(run, model, "explain", "firing"), indexes=times,
                     columns=cols.partition(np.full(n, r)))
    k = np.argmax(w, axis=1)
    peak = w[np.arange(n), k]
    cols = rr.Points2D.columns(positions=np.column_stack([rule_x(r)[k], -peak - 0.06]),
                               labels=(pd.Series(peak).map("{:.2f}".format)).to_numpy(),
                               colors=np.broadcast_to(CLUSTER_COLORS[1], (n, 3)),
                               radii=np.full(n, rr.Radius.ui_points(0.5), dtype=np.float32))
    rec.send_columns(model_path(run, model, "explain", "firing", "top"), indexes=times, columns=cols)


def _log_firing_axis(rec: rr.RecordingStream, run: Run, model: str, r: int) -> None:
    """Rule numbers under the bars (every other one past 12 rules), grid lines at w = 0.5 and 1, labelled on the
    left, clear of the strongest bar's label."""
    xs = rule_x(r)
    step = 1 if r <= 12 else 2
    grey = (150, 150, 150)
    base = model_path(run, model, "explain", "firing_axis")
    rec.log(base, _firing_axis_lines(), static=True)
    spots = np.vstack([np.column_stack([xs[::step], np.full(xs[::step].size, 0.06)]), [[-0.24, -0.5], [-0.24, -1.0]]])
    rec.log(base + "/labels", rr.Points2D(spots, labels=[f"R{k + 1}" for k in range(0, r, step)] + ["0.5", "1"],
                                          colors=[grey], radii=rr.Radius.ui_points(0.5)), static=True)


def verdicts(rows: pd.DataFrame, w: np.ndarray, rule_names: list[str], real: np.ndarray | None = None,
             titles: list[str] | None = None) -> list[str]:
    """One markdown paragraph per epoch: output against T2, the verdict, the strongest rules, and the inputs
    in their own units (`real` (n, D), titled by `titles`) when given."""
    out, thr = floats(rows, "output"), floats(rows, "threshold")
    flagged = rows["flagged"].to_numpy(dtype=bool) if "flagged" in rows else out > thr
    total = np.maximum(w.sum(axis=1), 1e-300)
    order = np.argsort(-w, axis=1)[:, :2]
    text = []
    for i, t in enumerate(floats(rows, "t_s")):
        cmp, word = (">", "**flagged**") if flagged[i] else ("<=", "not flagged")
        top = "; ".join(f"R{k + 1} ({rule_names[k]}) w={w[i, k]:.2f}, {100 * w[i, k] / total[i]:.0f} %"
                        for k in order[i])
        inputs = "" if real is None or titles is None else "\n\nInputs: " + ", ".join(
            f"{name} {v:.3g}" for name, v in zip(titles, real[i], strict=False)) + "."
        text.append(f"t = {t:.1f} s: output {out[i]:.2f} m {cmp} T2 {thr[i]:.2f} m, {word}.\n\n"
                    f"Strongest rules: {top}.{inputs}")
    return text

