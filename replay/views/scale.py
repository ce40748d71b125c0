"""A metre scale bar for the local 2D views (Navigation's east/north plot, KMCDF's fixes around the truth).

Rerun 0.41's 2D views have no scale of their own, so a bar is drawn as data in the view's metres: a line
of a round length (1, 2 or 5 x 10^k m, about a fifth of the view's width) with end ticks and its length
written above it, in the lower left corner of the view's default bounds (y down, as replay.views.common
says: the largest y is the bottom of the screen).
"""

from __future__ import annotations

import math

import numpy as np
import rerun as rr

SCALE_RGB = (150, 150, 150)
SHARE = 0.2
"""The bar's length is the longest round length no longer than this share of the view's width."""


def nice_length(span_m: float, share: float = SHARE) -> float:
    """The longest 1-2-5 x 10^k length (m) no longer than `share` of `span_m` (1 m for a degenerate span)."""
    target = share * span_m
    if not math.isfinite(target) or target <= 0:
        return 1.0
    decade = 10.0 ** math.floor(math.log10(target))
    return max(m * decade for m in (1.0, 2.0, 5.0) if m * decade <= target * (1 + 1e-9))


def scale_bar(x_range: tuple[float, float], y_range: tuple[float, float]) -> tuple[list[np.ndarray], np.ndarray, float]:
    """The bar of a view with these default bounds (view units, y down): its strips (the bar and two end
    ticks), where its label goes, and its length in metres."""
    (x0, x1), (y0, y1) = x_range, y_range
    width, height = x1 - x0, y1 - y0
    length = nice_length(width)
    # inside the rim where KMCDF draws the fixes beyond its frame (replay.views.positioning.RIM)
    left, base = x0 + 0.08 * width, y1 - 0.09 * height
    tick = 0.015 * max(height, width)
    strips = [np.array([[left, base], [left + length, base]]),
              np.array([[left, base - tick], [left, base + tick]]),
              np.array([[left + length, base - tick], [left + length, base + tick]])]
    # the label's box is centred on its point: clear of the bar
    return strips, np.array([[left + 0.5 * length, base - 3.5 * tick]]), length


def label(length_m: float) -> str:
    """The bar's text: "50 m", "2 km", "0.5 m"."""
    return f"{length_m / 1000:g} km" if length_m >= 1000 else f"{length_m:g} m"


def log_scale_bar(rec: rr.RecordingStream, path: str, x_range: tuple[float, float],
                  y_range: tuple[float, float]) -> float:
    """Log the bar (static) under `path` for a view with these default bounds; its length in metres."""
    strips, at, length = scale_bar(x_range, y_range)
    rec.log(path + "/bar", rr.LineStrips2D(strips, colors=[SCALE_RGB], radii=rr.Radius.ui_points(1.5),
                                           draw_order=50.0), static=True)
    rec.log(path + "/length", rr.Points2D(at, labels=[label(length)], colors=[SCALE_RGB],
                                          radii=rr.Radius.ui_points(0.1), show_labels=True, draw_order=50.0),
            static=True)
    return length
