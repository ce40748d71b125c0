"""The report's figures, drawn with matplotlib and embedded as SVG data URIs (nothing fetched at view time).

Figures are built on `matplotlib.figure.Figure` directly (no pyplot, no global
backend state), with the same colour per method as every other picture
(replay.review.palette). Times are mission seconds from the trial start.
"""

from __future__ import annotations

import base64
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import NullLocator

from replay.review.palette import method_hex

HIT, FALSE_ALARM, MISS, TRUTH = "#1b9e77", "#d62728", "#4b3a9e", "#222222"
TRAINING_GREY = "#ececec"
# pale fills under the marks, none of them near a mark's colour
KIND_COLORS = {"stale": "#ffe9a8", "drift": "#f6c9d6", "outlier": "#bcdcf2", "labelled": "#f6dcb4"}
MIN_SPAN_S = 6.0        # a one-epoch interval (an outlier) still shows at the scale of a whole mission


@dataclass
class Lane:
    """One row of the detection timeline: a name and the mission seconds of its marks."""

    name: str
    hits: np.ndarray = field(default_factory=lambda: np.empty(0))
    false_alarms: np.ndarray = field(default_factory=lambda: np.empty(0))
    misses: np.ndarray = field(default_factory=lambda: np.empty(0))
    truth: np.ndarray | None = None          # a truth lane: the labelled anomalous epochs


@dataclass(frozen=True)
class Span:
    """A shaded interval on the timeline: which lanes (by index), [start, end] s and a kind."""

    first_lane: int
    last_lane: int
    start_s: float
    end_s: float
    kind: str


def figure_uri(fig: Figure, tight: bool = True) -> str:
    """The figure as a data:image/svg+xml URI (no creation date, so a report is the same for the same run).

    `tight` crops to what is drawn (legends outside the axes included), at the cost of one more layout pass.
    """
    buf = io.BytesIO()
    # text as text (a third of the size; the browser's sans font); element ids from a fixed salt, not random
    with rc_context({"svg.fonttype": "none", "svg.hashsalt": "auvreplay"}):
        fig.savefig(buf, format="svg", bbox_inches="tight" if tight else None, metadata={"Date": None})
    return "data:image/svg+xml;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _t_a_line(ax: Axes, t_a: float) -> None:
    ax.axvline(t_a, color="#444444", ls="--", lw=1.0)


def cdf_figure(errors: dict[str, np.ndarray], labels: dict[str, str], window: str) -> Figure:
    """Empirical CDFs of horizontal error, one line per method in `labels`' order, on a log error axis."""
    fig = Figure(figsize=(11, 5.2))
    ax = fig.add_subplot()
    for method, label in labels.items():
        e = np.sort(np.asarray(errors.get(method, []), float))
        e = e[np.isfinite(e) & (e > 0)]
        if not len(e):
            continue
        ax.step(e, np.arange(1, len(e) + 1) / len(e), where="post", color=method_hex(method), lw=1.6, label=label)
    ax.set_xscale("log")
    ax.set_xlabel("horizontal error against GPS (m, log scale)")
    ax.set_ylabel("fraction of epochs with error ≤ x")
    ax.set_ylim(0, 1.01)
    ax.set_yticks(np.linspace(0, 1, 11))
    ax.axhline(0.5, color="#999999", lw=0.7, ls=":")
    ax.axhline(0.9, color="#999999", lw=0.7, ls=":")
    ax.grid(True, which="both", color="#eeeeee", lw=0.6)
    ax.set_title(f"Error CDF, {window}", fontsize=11)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=9, frameon=False, title="method (p50, p90)")
    return fig


def series_figure(series: dict[str, tuple[np.ndarray, np.ndarray]], titles: dict[str, str], t_a: float,
                  end_s: float) -> Figure:
    """Horizontal error over mission time, one small panel per method (titles' order), t_a dashed; every panel
    labels its time axis in mission seconds."""
    methods = [m for m in titles if m in series]
    cols = 2
    rows = max(1, -(-len(methods) // cols))
    height = 2.1 * rows + 0.6
    fig = Figure(figsize=(12, height))
    # a fixed layout: tight_layout over a dozen log axes costs seconds and finds the same margins
    # hspace leaves room under each row for its own time labels (a shared axis would label the bottom row only)
    fig.subplots_adjust(left=0.06, right=0.99, top=1 - 0.3 / height, bottom=0.5 / height, hspace=0.75, wspace=0.12)
    axes = fig.subplots(rows, cols, sharex=True, sharey=True, squeeze=False)
    top = max([float(np.nanmax(e)) for _, e in series.values() if len(e) and np.isfinite(e).any()] + [1.0])
    decades = 10.0 ** np.arange(-1, math.ceil(math.log10(top * 1.5)))
    for ax, method in zip(axes.ravel(), methods):
        t, e = series[method]
        ax.plot(t, np.maximum(e, 1e-2), color=method_hex(method), lw=0.9)
        _t_a_line(ax, t_a)
        ax.set_yscale("log")
        ax.yaxis.set_minor_locator(NullLocator())
        ax.set_yticks(decades, labels=[f"{d:g}" for d in decades])    # every decade, read as plain metres
        ax.set_ylim(0.1, top * 1.5)
        ax.set_xlim(0, end_s)
        ax.grid(True, which="major", color="#eeeeee", lw=0.6)
        ax.set_title(titles[method], fontsize=9, loc="left")
        ax.set_ylabel("m", fontsize=8)
        ax.tick_params(labelsize=8, labelbottom=True)      # every row reads its time, not only the bottom one
        ax.set_xlabel("mission time (s)", fontsize=8, labelpad=1)
    for ax in axes.ravel()[len(methods):]:
        ax.set_visible(False)
    return fig


def timeline_figure(lanes: Sequence[Lane], spans: Sequence[Span], t_a: float, end_s: float) -> Figure:
    """Detection lanes (hits, false alarms, misses after t_a) under truth lanes, anomaly intervals shaded."""
    n = len(lanes)
    fig = Figure(figsize=(13, 0.42 * n + 1.6))
    ax = fig.add_subplot()
    ax.axvspan(0, min(t_a, end_s), color=TRAINING_GREY, zorder=0)
    for s in spans:
        mid, half = 0.5 * (s.start_s + s.end_s), 0.5 * max(s.end_s - s.start_s, MIN_SPAN_S)
        ax.fill_between([mid - half, mid + half], n - 1 - s.last_lane - 0.45,
                        n - 1 - s.first_lane + 0.45, color=KIND_COLORS.get(s.kind, "#dddddd"), lw=0, zorder=1)
    for i, lane in enumerate(lanes):
        y = n - 1 - i
        if lane.truth is not None:
            ax.vlines(lane.truth, y - 0.35, y + 0.35, color=TRUTH, lw=0.8, zorder=3)
            continue
        ax.vlines(lane.hits, y - 0.35, y + 0.35, color=HIT, lw=1.0, zorder=3)
        ax.vlines(lane.false_alarms, y, y + 0.4, color=FALSE_ALARM, lw=1.0, zorder=3)
        ax.vlines(lane.misses, y - 0.4, y, color=MISS, lw=1.0, zorder=3)
    if t_a <= end_s:
        _t_a_line(ax, t_a)
        ax.text(t_a, n - 0.35, " t_a", fontsize=8, va="bottom")
    ax.set_yticks(range(n))
    ax.set_yticklabels([lane.name for lane in reversed(lanes)], fontsize=8)
    ax.set_ylim(-0.6, n - 0.1)
    ax.set_xlim(0, end_s)
    ax.set_xlabel("mission time (s from the trial start)")
    ax.grid(True, axis="x", color="#eeeeee", lw=0.6)
    kinds = sorted({s.kind for s in spans})
    handles = [Line2D([], [], color=TRUTH, lw=1.5, label="truth: labelled anomalous epoch"),
               Line2D([], [], color=HIT, lw=2, label="hit (flagged, anomalous)"),
               Line2D([], [], color=FALSE_ALARM, lw=2, label="false alarm (upper half)"),
               Line2D([], [], color=MISS, lw=2, label="miss (lower half)"),
               Patch(color=TRAINING_GREY, label="training, not scored (before t_a)")]
    handles += [Patch(color=KIND_COLORS.get(k, "#dddddd"), label=f"interval: {k}") for k in kinds]
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.5 / max(n, 1) - 0.08),
              ncol=4, fontsize=8, frameon=False)
    return fig


def tracks_figure(tracks: dict[str, tuple[np.ndarray, np.ndarray]], colours: dict[str, str]) -> Figure:
    """Every track in local metres (east, north of the trial's origin), one line per vehicle and source."""
    fig = Figure(figsize=(8, 6.5))
    ax = fig.subplots()
    for name, (east, north) in tracks.items():
        ax.plot(east, north, lw=1.0, color=colours.get(name), label=name)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, color="#eeeeee", lw=0.6)
    ax.set_xlabel("east (m)", fontsize=8)
    ax.set_ylabel("north (m)", fontsize=8)
    ax.tick_params(labelsize=8)
    if tracks:
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return fig
