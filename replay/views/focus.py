"""Which methods a recording shows at first: the focus set; the others are hidden, one click away.

By default the focus is the truth, the best method of each scoreboard group
(cooperative, USBL positioning), the best detector (the verdict's),
chi-square and paper A's ANFIS: a review
starts from the verdict and its two references instead of sixteen tracks
in one bundle. `--focus a,b,c` names the set, `--focus all` shows every
method. GPS and the other position sources are always shown; the INS and
a vehicle's own dead reckoning (restarted at each fix) are hidden by the
default focus of a run whose cooperative methods were scored (they sit on
the GPS there), and shown otherwise. A hidden track is a Rerun visibility
override, so the blueprint panel's eye brings it back.
"""

from __future__ import annotations

from collections.abc import Sequence

import rerun.blueprint as rrb
from rerun.blueprint.api import VisualizerLike
from rerun.encodings import EntityPathLike

from replay.navigation.review import DR_METHOD
from replay.review.scoreboard import best_detector, best_of_groups, scoreboard
from replay.stack.methods import METHOD_TABLE
from replay.views.common import Run, track_pairs

ALL = "all"
REFERENCES: tuple[str, ...] = ("chi_square", "anfis")   # the paper's baseline and its ANFIS
BESIDE_GPS: tuple[str, ...] = ("ins", DR_METHOD)          # sources that sit on the GPS while it is there


def default_focus(metrics: dict) -> tuple[str, ...]:
    """The best method of each group (by p50), the best detector, then chi-square and ANFIS, in that order."""
    rows = scoreboard(metrics)
    best = [r.method for r in best_of_groups(rows).values()]
    detector = best_detector(rows)
    return tuple(dict.fromkeys([*best, *([detector.method] if detector else []), *REFERENCES]))


def focus_of(run: Run, focus: Sequence[str] | None) -> tuple[str, ...] | None:
    """The run's focus set: the given one, its default, or None for every method (`all`)."""
    if focus is None:
        return default_focus(run.review.metrics)
    return None if ALL in focus else tuple(focus)


def hidden_methods(run: Run, focus: Sequence[str] | None) -> list[str]:
    """The methods of the method table the run drew that its focus leaves out, in table order."""
    key = "hidden " + repr(None if focus is None else tuple(focus))
    review = run.review
    return list(run.memo(key, (review.tracks, review.errors, review.metrics), lambda: _hidden(run, focus)))


def _hidden(run: Run, focus: Sequence[str] | None) -> list[str]:
    shown = focus_of(run, focus)
    if shown is None:
        return []
    drawn = set(run.review.methods)
    for frame, col in ((run.review.tracks, "source"), (run.review.errors, "method")):
        if col in frame:
            drawn |= set(frame[col].astype(str).unique())
    hidden = [m for m in METHOD_TABLE if m in drawn and m not in shown]
    cooperative = any(r.group == "cooperative" for r in scoreboard(run.review.metrics))
    if focus is None and cooperative:
        hidden += [s for s in BESIDE_GPS if s in drawn]
    return hidden


def hide(runs: list[Run], focus: Sequence[str] | None, view: str) -> dict[EntityPathLike, VisualizerLike]:
    """Visibility overrides hiding every out-of-focus method's entities of one view family.

    `view` is "map" or "local" (per vehicle and method), or "error" and "cdf" (per follower and method).
    """
    out: dict[EntityPathLike, VisualizerLike] = {}
    for run in runs:
        hidden = hidden_methods(run, focus)
        if not hidden:
            continue
        if view in ("map", "local"):
            keys = [(v, s) for v, s in track_pairs(run) if s in hidden]
            # every leaf entity: a Spatial view does not carry a parent's visibility to its children
            out.update({run.path(view, v, s, leaf): rrb.EntityBehavior(visible=False) for v, s in keys
                        for leaf in ("track", "position", "trail")})
        else:
            followers = sorted({str(k[0]) for k, _ in run.groups(run.review.errors, ["follower"])})
            if view == "error":
                out.update({run.path("series", "error", f, m): rrb.EntityBehavior(visible=False)
                            for f in followers for m in hidden})
            else:
                out.update({run.path("cdf", f, m, leaf): rrb.EntityBehavior(visible=False) for f in followers
                            for m in hidden for leaf in ("curve", "final", "percentiles")})
    return out


def focus_note(runs: list[Run], focus: Sequence[str] | None) -> str:
    """One line for view titles: what is hidden and how to show it ('' when nothing is)."""
    hidden = sorted({m for r in runs for m in hidden_methods(r, focus)})
    if not hidden:
        return ""
    return f"{len(hidden)} more methods hidden (view --focus all)"


__all__ = ["ALL", "default_focus", "focus_note", "focus_of", "hidden_methods", "hide"]
