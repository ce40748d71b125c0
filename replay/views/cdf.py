"""Error CDFs as a plot: every method's empirical CDF of its errors after t_a, growing with mission time.

Rerun 0.41 plots scalars against time only (a time-series x axis is a timeline), so the CDF is drawn
in a 2D view with its own axes: x is the horizontal error on a log scale (numbered ticks in metres),
y the fraction of errors up to x (gridlines numbered 0 to 100 %), and a legend in the method colours,
ranked as the scoreboard ranks them. Only errors inside the metrics window (from t_a) count, so the
last snapshot's p50/p90 are the scoreboard's.

Entities under a run prefix P, for each follower F:
- ``P/cdf/F/<method>/curve`` LineStrips2D on `time`/`mission_s`: the CDF so far, at up to
  `CDF_SNAPSHOTS` instants from t_a; ``.../percentiles`` Points2D marking p50, p90, p95;
  ``.../final`` static and faint: the whole window's CDF (what the curve grows into);
- ``P/cdf/F/table`` TextDocument: p50/p90/p95 of each method from t_a up to the instant;
- ``P/cdf/F/axes`` static, and ``P/cdf/F/legend`` (its labels on `time`/`mission_s`: each method's
  p50 from t_a to the cursor, as the curves grow), shared by both runs of a comparison, under the first
  run's prefix.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import rerun as rr

from replay.review.scoreboard import scoreboard
from replay.views.common import Run, floats, method_rgb
from replay.views.lanes import training_end_s

CDF_SNAPSHOTS = 120
CDF_POINTS = 101
PERCENTILES = (0.50, 0.90, 0.95)
WIDTH, HEIGHT = 100.0, 100.0
"""Plot area in view units: x from 0 to WIDTH, y from 0 (0 %) up to -HEIGHT (100 %)."""
NICE = (1.0, 2.0, 5.0)
GRID_RGB, AXIS_RGB, TEXT_RGB = (128, 128, 128, 70), (128, 128, 128, 255), (128, 128, 128)


@dataclass(frozen=True)
class LogAxis:
    """The x axis: log10 of the error in metres, from `lo` to `hi` (metres)."""

    lo: float
    hi: float

    def x(self, error_m: np.ndarray) -> np.ndarray:
        """View x of errors (clipped to the axis: a curve never leaves the plot)."""
        e = np.clip(np.asarray(error_m, dtype=float), self.lo, self.hi)
        return WIDTH * (np.log10(e) - np.log10(self.lo)) / (np.log10(self.hi) - np.log10(self.lo))

    def error(self, x: np.ndarray) -> np.ndarray:
        """Metres at view x (the inverse of `x`)."""
        return self.lo * (self.hi / self.lo) ** (np.asarray(x, dtype=float) / WIDTH)

    def ticks(self) -> np.ndarray:
        """1-2-5 ticks inside [lo, hi]."""
        decades = np.arange(np.floor(np.log10(self.lo)), np.ceil(np.log10(self.hi)) + 1)
        t = (10.0 ** decades[:, None] * np.array(NICE)[None, :]).ravel()
        return t[(t >= self.lo * 0.999) & (t <= self.hi * 1.001)]


def error_axis(runs: list[Run]) -> dict[str, LogAxis]:
    """Per follower, the x axis holding every method's scored errors (1st to 99th percentile; beyond, curves
    run up the right edge)."""
    out: dict[str, list[np.ndarray]] = {}
    for run in runs:
        t_a = training_end_s(run)
        for (follower, _method), rows in run.groups(run.review.errors, ["follower", "method"]):
            v = floats(rows, "error_m")[floats(rows, "t_s") >= t_a]  # from t_a on, as the metrics count
            v = v[np.isfinite(v) & (v > 0)]
            if v.size:
                out.setdefault(str(follower), []).append(np.quantile(v, [0.01, 0.99]))
    axes = {}
    for follower, q in out.items():
        lo, hi = float(min(x[0] for x in q)), float(max(x[1] for x in q))
        lo = 10.0 ** np.floor(np.log10(max(lo, 1e-3)))
        hi = max(hi, lo * 10.0)
        axes[follower] = LogAxis(lo, float(10.0 ** (np.ceil(np.log10(hi) * 4) / 4)))
    return axes


def expanding_quantiles(t_s: np.ndarray, values: np.ndarray, at_s: np.ndarray, probs: np.ndarray) -> np.ndarray:
    """Quantiles (len(at_s), len(probs)) of the finite values with t <= each instant; NaN rows where none.

    One sort of a (snapshots, n) matrix with later samples masked to +inf, then
    linear interpolation between order statistics (numpy's default "linear" rule).
    """
    ok = np.isfinite(values)
    t_s, values = t_s[ok], values[ok]
    seen = t_s[None, :] <= at_s[:, None]
    ordered = np.sort(np.where(seen, values[None, :], np.inf), axis=1)
    count = seen.sum(axis=1)
    pos = probs[None, :] * np.maximum(count - 1, 0)[:, None]
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, np.maximum(count - 1, 0)[:, None])
    frac = pos - lo
    if ordered.shape[1] == 0:
        return np.full((at_s.size, probs.size), np.nan)
    q_lo, q_hi = np.take_along_axis(ordered, lo, 1), np.take_along_axis(ordered, hi, 1)
    with np.errstate(invalid="ignore"):
        q = q_lo + frac * (q_hi - q_lo)
    return np.where((count > 0)[:, None], q, np.nan)


def snapshot_times(t_s: np.ndarray) -> np.ndarray:
    """At most CDF_SNAPSHOTS of the distinct finite times, evenly spread, the last always kept."""
    uniq = np.unique(t_s[np.isfinite(t_s)])
    if uniq.size <= CDF_SNAPSHOTS:
        return uniq
    return uniq[np.unique(np.linspace(0, uniq.size - 1, CDF_SNAPSHOTS).round().astype(np.int64))]


Growth = dict[str, tuple[np.ndarray, dict[str, np.ndarray]]]
"""Per follower: the snapshot instants and each method's p50 at them (what the legend shows over time)."""


def log_cdfs(rec: rr.RecordingStream, run: Run, axes: dict[str, LogAxis]) -> Growth:
    """The growing CDF of every method and the percentile table, per follower; each method's p50 at each snapshot
    (for `log_cdf_legend`)."""
    probs = np.linspace(0.0, 1.0, CDF_POINTS)
    marks = np.array(PERCENTILES)
    growth: Growth = {}
    t_a = training_end_s(run)
    by_method: dict[str, list[tuple[str, np.ndarray, np.ndarray]]] = {}
    for (follower, method), rows in run.groups(run.review.errors, ["follower", "method"]):
        t = floats(rows, "t_s")
        kept = t >= t_a  # from t_a on, as the metrics count
        if kept.any():
            by_method.setdefault(str(follower), []).append((str(method), t[kept], floats(rows, "error_m")[kept]))
    for f, methods in by_method.items():
        axis = axes.get(f)
        if axis is None:
            continue
        at = snapshot_times(np.concatenate([t for _, t, _ in methods]))
        table: dict[str, np.ndarray] = {}
        for m, t, e in methods:
            q = expanding_quantiles(t, e, at, np.concatenate([probs, marks]))
            _log_curve(rec, run, f, m, at, q, axis)
            table[m] = q[:, CDF_POINTS:]
        _log_table(rec, run, f, at, table)
        growth[f] = (at, {m: v[:, 0] for m, v in table.items()})
    return growth


def log_cdf_frame(rec: rr.RecordingStream, runs: list[Run], axes: dict[str, LogAxis]) -> None:
    """Axes, ticks and gridlines of each follower's CDF plot (static, under the first run)."""
    for follower, axis in axes.items():
        _log_axes(rec, runs[0].path("cdf", follower, "axes"), axis)


def log_cdf_legend(rec: rr.RecordingStream, runs: list[Run], growth: list[Growth],
                   hidden: frozenset[str] = frozenset()) -> None:
    """Each follower's legend (under the first run): the methods in their colours, best first, each with its p50
    from t_a up to the cursor, as the curves grow; the `hidden` methods (out of focus, replay.views.focus) left
    out."""
    for follower in {f for g in growth for f in g}:
        _log_legend(rec, runs, follower, runs[0].path("cdf", follower, "legend"),
                    [g.get(follower, (np.zeros(0), {})) for g in growth], hidden)


def _log_curve(rec: rr.RecordingStream, run: Run, follower: str, method: str, at: np.ndarray,
               q: np.ndarray, axis: LogAxis) -> None:
    ok = np.isfinite(q[:, 0])
    if not ok.any():
        return
    at, q = at[ok], q[ok]
    k = at.size
    rgb = np.array(method_rgb(method, run.index), dtype=np.uint8)
    curve, marks = q[:, :CDF_POINTS], q[:, CDF_POINTS:]
    ys = -np.linspace(0.0, 1.0, CDF_POINTS) * HEIGHT
    strips = np.stack([axis.x(curve), np.broadcast_to(ys, curve.shape)], axis=-1)          # (k, points, 2)
    rec.send_columns(run.path("cdf", follower, method, "curve"), indexes=run.times(at),
                     columns=rr.LineStrips2D.columns(strips=np.ascontiguousarray(strips), colors=np.tile(rgb, (k, 1)),
                                                     radii=np.full(k, rr.Radius.ui_points(1.5), dtype=np.float32)))
    # the whole window's CDF, faint and static: the plot reads before the cursor reaches the end
    rec.log(run.path("cdf", follower, method, "final"),
            rr.LineStrips2D([strips[-1]], colors=[(*rgb.tolist(), 70)], radii=rr.Radius.ui_points(1.0)), static=True)
    n_marks = len(PERCENTILES)
    pos = np.stack([axis.x(marks.ravel()), np.tile(-np.array(PERCENTILES) * HEIGHT, k)], axis=-1)
    cols = rr.Points2D.columns(positions=pos, colors=np.tile(rgb, (k * n_marks, 1)),
                               radii=np.full(k * n_marks, rr.Radius.ui_points(3.5), dtype=np.float32))
    rec.send_columns(run.path("cdf", follower, method, "percentiles"), indexes=run.times(at),
                     columns=cols.partition(np.full(k, n_marks)))


def _log_axes(rec: rr.RecordingStream, path: str, axis: LogAxis) -> None:
    ticks = axis.ticks()
    tx = axis.x(ticks)
    levels = np.array([0.0, 0.25, *PERCENTILES, 1.0])
    grid = ([np.array([[x, 0.0], [x, -HEIGHT]]) for x in tx]
            + [np.array([[0.0, -p * HEIGHT], [WIDTH, -p * HEIGHT]]) for p in levels])
    rec.log(path + "/grid", rr.LineStrips2D(grid, colors=[GRID_RGB], radii=rr.Radius.ui_points(0.5)), static=True)
    rec.log(path + "/lines", rr.LineStrips2D([np.array([[0.0, -HEIGHT], [0.0, 0.0], [WIDTH, 0.0]])],
                                             colors=[AXIS_RGB], radii=rr.Radius.ui_points(1.0)), static=True)
    tick_text = [f"{t:g}" for t in ticks]
    rec.log(path + "/x_ticks", rr.Points2D(np.column_stack([tx, np.full(tx.size, 2.5)]), labels=tick_text,
                                           colors=[TEXT_RGB], radii=rr.Radius.ui_points(0.1)), static=True)
    rec.log(path + "/y_ticks", rr.Points2D(np.column_stack([np.full(levels.size, -7.0), -levels * HEIGHT]),
                                           labels=[f"{100 * p:.0f} %" for p in levels], colors=[TEXT_RGB],
                                           radii=rr.Radius.ui_points(0.1)), static=True)
    rec.log(path + "/titles", rr.Points2D([[WIDTH / 2, 7.5], [WIDTH / 2, -HEIGHT - 6.0]],
                                          labels=["horizontal error vs GPS (m, log scale)",
                                                  "share of errors <= x, after t_a"],
                                          colors=[TEXT_RGB], radii=rr.Radius.ui_points(0.1)), static=True)


def legend_p50(growth: list[tuple[np.ndarray, dict[str, np.ndarray]]], method: str,
               at: np.ndarray) -> np.ndarray:
    """(len(at), runs) p50 of a method in each run at each instant: its latest snapshot at or before the
    instant (NaN before the first)."""
    out = np.full((at.size, len(growth)), np.nan)
    for i, (t, p50) in enumerate(growth):
        v = p50.get(method)
        if v is None or t.size == 0:
            continue
        k = np.searchsorted(t, at, side="right") - 1
        out[k >= 0, i] = v[k[k >= 0]]
    return out


def _log_legend(rec: rr.RecordingStream, runs: list[Run], follower: str, path: str,
                growth: list[tuple[np.ndarray, dict[str, np.ndarray]]], hidden: frozenset[str] = frozenset()) -> None:
    """One entry per method, its name and p50 so far in its colour, best first (the first run's scoreboard order).

    The names and positions are static; the labels are sent once per snapshot instant (and once at t = 0,
    before t_a, with no figure), so the legend reads the same p50 as the curve at the cursor.
    """
    present = [{str(k[1]) for k, _ in r.groups(r.review.errors, ["follower", "method"]) if str(k[0]) == follower}
               for r in runs]
    ranked = [r.method for r in scoreboard(runs[0].review.metrics) if r.method in present[0]]
    methods = [m for m in ranked + sorted(set().union(*present) - set(ranked)) if m not in hidden]
    if not methods:
        return
    at = np.unique(np.concatenate([np.zeros(1), *(t for t, _ in growth)]))
    figures = np.stack([legend_p50(growth, m, at) for m in methods], axis=1)        # (instants, methods, runs)
    text = np.where(np.isfinite(figures), np.char.mod("%.2f", np.nan_to_num(figures)), "-")
    joined = text[..., 0] if len(runs) == 1 else np.char.add(np.char.add(text[..., 0], " / "), text[..., 1])
    labels = np.char.add(np.char.add(np.array([f"{m}  p50 " for m in methods])[None, :], joined), " m")
    colours = [method_rgb(m, 0) for m in methods]
    if len(runs) == 2:       # one line per method, both runs' p50 (A / B); B's curves are the shade
        labels = np.concatenate([np.full((at.size, 1), "A / B: B's curves lighter or darker"), labels], axis=1)
        colours.insert(0, (128, 128, 128))
    n = labels.shape[1]
    step = min(8.0, 0.6 * HEIGHT / n)     # a line of text apart at the sizes the tab gives the plot
    y = -step * np.arange(n)[::-1] - step
    x0 = 0.64 * WIDTH
    rec.log(path + "/names", rr.Points2D(np.column_stack([np.full(n, x0 + 17.0), y]), colors=colours,
                                         radii=rr.Radius.ui_points(0.1)), static=True)
    rec.send_columns(path + "/names", indexes=runs[0].times(at),
                     columns=rr.Points2D.columns(labels=labels.ravel().tolist()).partition(np.full(at.size, n)))


def _log_table(rec: rr.RecordingStream, run: Run, follower: str, at: np.ndarray,
               table: dict[str, np.ndarray]) -> None:
    """A markdown table of each method's percentiles from t_a up to the instant, one document per snapshot."""
    if not table or at.size == 0:
        return
    t_a = training_end_s(run)
    head = "| method | " + " | ".join(f"p{int(p * 100)} (m)" for p in PERCENTILES) + " |\n|---|" + "---:|" * len(
        PERCENTILES) + "\n"
    order = sorted(table, key=lambda m: (np.nan_to_num(table[m][-1, 0], nan=np.inf), m))
    # every figure formatted at once: (methods, instants) cells of the percentiles joined
    cells = [" | ".join(c) for c in np.char.mod("%.2f", np.stack([table[m] for m in order])).reshape(
        -1, len(PERCENTILES)).tolist()]
    rows = [[f"| {m} | {cells[j * at.size + i]} |" for j, m in enumerate(order)] for i in range(at.size)]
    tag = f" [{run.tag}]" if run.tag else ""
    docs = [f"**Errors of {follower}{tag} from t_a = {t_a:.0f} s to {t:.0f} s** (mission seconds; the metrics "
            f"window, so at the end these are the scoreboard's p50/p90)\n\n" + head + "\n".join(rows[i])
            for i, t in enumerate(at)]
    if at[0] > 0:            # before the first scored error the view would say "(empty)": say why instead
        at = np.r_[0.0, at]
        docs.insert(0, f"**Errors of {follower}{tag}**: none is counted before t_a = {t_a:.0f} s (the metrics "
                       "window); move the cursor past it to see the percentiles grow.")
    rec.send_columns(run.path("cdf", follower, "table"), indexes=run.times(at),
                     columns=rr.TextDocument.columns(text=docs, media_type=["text/markdown"] * at.size))
