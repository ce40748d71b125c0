"""The method table: one entry per method of the stack, and everything that lists methods reads it.

An entry says what a method is (filter, detector or positioning), how its
filter runs, which detector it builds, which inputs of a trial it needs, how
it is shown (label, short name, colour, score plot) and how it explains a
decision (its why-line). The config's method sets, the runner, `evaluate`,
the scoreboard, the lanes, the why panels, the palette and `--set methods=`
all read `METHOD_TABLE`.

Adding a detector is one module (the detector class and its ``why_line``)
plus one `Method` entry in `METHOD_TABLE` below, plus its tests. A method
defined outside this package is added with `register` (for example from a
module named in ``$AUVREPLAY_PLUGINS``, a comma-separated list of modules
imported when this table is first read).
"""

from __future__ import annotations

import importlib
import math
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from replay.events import EpochResult
from replay.stack.config import ConfigError, StackConfig
from replay.stack.detectors import (
    anfis_detector,
    anfis_hybrid,
    chi_square,
    cusum,
    drift_reference,
    dual_threshold,
    fix_aware,
    stale_aware,
)
from replay.stack.detectors.base import Detector
from replay.stack.detectors.why_text import generic_why
from replay.stack.features import FEATURE_NAMES, PAPER_FEATURES

DetectorFactory = Callable[[StackConfig], Detector]
WhyLine = Callable[[EpochResult, object | None], str]

KINDS: tuple[str, ...] = ("filter", "detector", "positioning")
"""What a method is: a filter of the follower's position, an ACKF isolated by a detector, or a USBL/LBL fix."""

# the inputs a method may need, by name, with the phrase a skip note uses ("ackf: needs modem ranges from a leader")
INPUTS: dict[str, str] = {
    "dvl": "DVL velocities on the vehicle",
    "ranges": "modem ranges from a leader with a position",
    "gps": "GPS fixes on the vehicle",
    "usbl": "USBL fixes",
}
RGB = tuple[int, int, int]


@dataclass(frozen=True)
class Method:
    """One method of the stack: what it runs, what it needs and how the views show it.

    ``filter`` is how the runner drives it: "dr" (dead reckoning only),
    "ckf" and "ackf" (every range used), "detect" (an ACKF whose detector
    may isolate a range; ``factory`` builds the detector) or "usbl" (the
    engine's positioning of USBL epochs). ``features`` are the feature
    columns the detector reads (`replay.stack.features.FEATURE_NAMES`
    names): paper A's (f1, f2, f3), trained on the recorded window only, or
    every column, trained on the hybrid database too.
    """

    name: str
    kind: str
    filter: str
    needs: tuple[str, ...]
    label: str
    short: str
    colour: RGB                      # replay.review.palette: distinct for every pair, and for colour-blind eyes
    factory: DetectorFactory | None = None
    features: tuple[str, ...] = ()
    why: WhyLine = generic_why
    default: bool = False            # run by a replay that names no methods
    score_plot: tuple[str, str] | None = None   # (title, what it compares) of its plot beside its threshold
    anfis_plot: bool = False         # drawn on the ANFIS plot: its output against its T2, in metres
    anfis_model: bool = False        # an ANFIS model: the ANFIS tab draws its MFs, rules and training, one view each
    pooled_training: bool = False    # trained on every leader's rows together, whatever anfis.model says
    threaded_training: bool = False  # whole-population numpy training: trained on threads beside its like
    calibrated: bool = False         # its threshold flags the FPR target of the training trial's normals after t_a

    @property
    def detects(self) -> bool:
        """True for a method whose detector decides on range epochs."""
        return self.filter == "detect"

    @property
    def wide(self) -> bool:
        """True for a detector reading more than paper A's (f1, f2, f3): it needs the feature tracker."""
        return self.detects and self.features != PAPER_FEATURES

    def missing(self, available: set[str] | frozenset[str]) -> list[str]:
        """The inputs this method needs that are not in `available`, in the order of `needs`."""
        return [n for n in self.needs if n not in available]


def _anfis(trainer: str, compensation: bool) -> DetectorFactory:
    """A factory building an AnfisDetector for one trainer and mode."""
    def build(config: StackConfig) -> Detector:
        """A fresh AnfisDetector for this trainer and mode."""
        return anfis_detector.AnfisDetector(config, trainer=trainer, compensation=compensation)
    return build


_DR, _RANGES, _TRAINED, _USBL = ("dvl",), ("dvl", "ranges"), ("dvl", "ranges", "gps"), ("usbl",)
_PAPER, _WIDE = PAPER_FEATURES, FEATURE_NAMES


def _positioning(name: str, label: str, colour: RGB) -> Method:
    """A positioning method of the USBL epochs (KMCDF and its delay-only baselines)."""
    return Method(name, "positioning", "usbl", _USBL, label, name, colour)


METHOD_TABLE: dict[str, Method] = {m.name: m for m in (
    Method("dead_reckoning", "filter", "dr", _DR, "dead reckoning (DVL + heading)", "dr", (230, 159, 0),
           default=True),
    Method("ckf", "filter", "ckf", _RANGES, "CKF, every range used", "ckf", (0, 114, 178), default=True),
    Method("ackf", "filter", "ackf", _RANGES, "adaptive CKF, every range used", "ackf", (86, 180, 233),
           default=True),
    Method("chi_square", "detector", "detect", _TRAINED, "ACKF + chi-square test", "chi2", (213, 94, 0),
           chi_square.ChiSquareDetector, _PAPER, chi_square.why_line, default=True,
           score_plot=("chi_square: f2 vs gate", "f2 against its chi-square gate")),
    Method("dual_threshold", "detector", "detect", _TRAINED, "ACKF + dual threshold (BP net, CUSUM)", "dual",
           (75, 105, 255), dual_threshold.DualThresholdDetector, _PAPER, dual_threshold.why_line, default=True,
           score_plot=("dual_threshold vs 1", "max(f2/gate, CUSUM S/h) against 1")),
    Method("anfis", "detector", "detect", _TRAINED, "ACKF + ANFIS (hybrid learning)", "anfis", (0, 158, 115),
           _anfis("hybrid", False), _PAPER, anfis_detector.why_line, anfis_plot=True, anfis_model=True,
           default=True),
    Method("anfis_aqpso", "detector", "detect", _TRAINED, "ACKF + ANFIS (AQPSO-GA)", "aqpso", (240, 180, 135),
           _anfis("aqpso_ga", False), _PAPER, anfis_detector.why_line, anfis_plot=True, anfis_model=True,
           default=True, threaded_training=True),
    Method("anfis_compensation", "detector", "detect", _TRAINED, "ACKF + ANFIS range compensation", "comp",
           (105, 135, 15), _anfis("hybrid", True), _PAPER, anfis_detector.why_line, anfis_plot=True, anfis_model=True,
           default=True),
    # detectors on filter-independent features: their hybrid database and extra ANFIS training cost about
    # half again a replay's time, so they run when named (`--set methods=...`), in `evaluate` and in `demo`
    Method("cusum_drift", "detector", "detect", _TRAINED, "ACKF + CUSUM of the drift residual", "cusum",
           (255, 0, 90), cusum.CusumDriftDetector, _WIDE, cusum.why_line,
           score_plot=("cusum_drift S vs h (sd)", "max(S+, S-) of drift_z against h, in sd")),
    Method("anfis_hybrid", "detector", "detect", _TRAINED, "ACKF + ANFIS on the hybrid database", "hybrid",
           (195, 0, 255), anfis_hybrid.HybridAnfisDetector, _WIDE, anfis_hybrid.why_line,
           score_plot=("anfis_hybrid vs thr (m)", "output against the threshold of its 2 % training FPR, in m"),
           anfis_model=True),
    Method("drift_reference", "detector", "detect", _TRAINED, "ACKF + DR error reference", "dref",
           (204, 121, 167), drift_reference.DriftReferenceDetector, _WIDE, drift_reference.why_line,
           score_plot=("drift_reference vs h (sd)",
                       "min(|drift_z|, h*|residual|/T1) against h, in sd (m before drift_z exists)"),
           pooled_training=True, calibrated=True),
    # drift_reference without a fresh USBL fix, chi-square with one (the drift residual is then the DR error
    # model's innovation, and the ACKF's separates better: docs/detection.md section 5)
    Method("fix_aware", "detector", "detect", _TRAINED, "ACKF + DR error reference, chi-square under a fresh fix",
           "fixaw", (120, 90, 60), fix_aware.FixAwareDetector, _WIDE, fix_aware.why_line,
           score_plot=("fix_aware vs h (sd)", "chi-square's h*sqrt(f2/gate) with a fresh fix, else drift_reference's"),
           pooled_training=True, calibrated=True),
    # fix_aware, and a repeated range judged by its error predicted now against T1 (the DR error model never
    # takes a repeated range, so its innovation there is the stale run's error: docs/detection.md section 5)
    Method("stale_aware", "detector", "detect", _TRAINED, "ACKF + DR error reference, stale ranges by their error",
           "stale", (0, 255, 255), stale_aware.StaleAwareDetector, _WIDE, stale_aware.why_line,
           score_plot=("stale_aware vs h (sd)", "h*(|e|/T1)^8 on a repeated range, else fix_aware's score"),
           pooled_training=True, calibrated=True),
    _positioning("kmcdf1", "KMCDF, delays only", (255, 0, 180)),
    _positioning("kmcdf2", "KMCDF, delays and phases", (240, 228, 66)),
    _positioning("gar", "GAR (geometric average)", (0, 210, 0)),
    _positioning("ear", "EAR (error-weighted average)", (225, 135, 255)),
    _positioning("lms", "least squares", (165, 195, 135)),
    _positioning("lhc", "linear hyperbolic", (105, 210, 105)),
)}
"""Method name -> its entry, in the order the views and tables list methods."""

_plugins_loaded = False


def register(method: Method) -> Method:
    """Add a method to the table (a detector defined outside this package); ConfigError on a clash or bad entry."""
    if method.name in METHOD_TABLE and METHOD_TABLE[method.name] != method:
        raise ConfigError(f"method {method.name!r} is already in the method table")
    if method.kind not in KINDS:
        raise ConfigError(f"method {method.name!r}: kind {method.kind!r} is not one of {', '.join(KINDS)}")
    unknown = [n for n in method.needs if n not in INPUTS]
    if unknown:
        raise ConfigError(f"method {method.name!r}: unknown inputs {', '.join(unknown)} (known: {', '.join(INPUTS)})")
    if method.detects and method.factory is None:
        raise ConfigError(f"method {method.name!r}: a detecting method needs a factory")
    METHOD_TABLE[method.name] = method
    return method


def _load_plugins() -> None:
    """Import the modules named in $AUVREPLAY_PLUGINS once (each registers its methods); ConfigError if one fails."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for name in filter(None, (s.strip() for s in os.environ.get("AUVREPLAY_PLUGINS", "").split(","))):
        try:
            importlib.import_module(name)
        except ImportError as exc:
            raise ConfigError(f"AUVREPLAY_PLUGINS: cannot import {name!r}: {exc}") from exc


def methods(kind: str | None = None) -> Iterator[Method]:
    """Every entry of the table (or of one kind), in table order."""
    _load_plugins()
    return (m for m in list(METHOD_TABLE.values()) if kind is None or m.kind == kind)


def method_names(kind: str | None = None, *, default: bool | None = None) -> tuple[str, ...]:
    """Names of the table's methods, of one kind and/or in (or out of) the default set."""
    return tuple(m.name for m in methods(kind) if default is None or m.default == default)


def runnable_names() -> tuple[str, ...]:
    """Every method the runner can drive (filters and detectors; positioning runs on USBL epochs anyway)."""
    return tuple(m.name for m in methods() if m.kind != "positioning")


def default_names() -> tuple[str, ...]:
    """What a replay runs when the configuration names no methods."""
    return tuple(m.name for m in methods() if m.default and m.kind != "positioning")


def detecting_names() -> tuple[str, ...]:
    """Every method whose detector decides on range epochs."""
    return method_names("detector")


def anfis_family() -> frozenset[str]:
    """The methods drawn on the ANFIS plot (paper A's ANFIS detectors)."""
    return frozenset(m.name for m in methods() if m.anfis_plot)


def anfis_models() -> tuple[str, ...]:
    """The methods with an ANFIS model of their own (the ANFIS tab's views), in table order."""
    return tuple(m.name for m in methods() if m.anfis_model)


def method(name: str) -> Method:
    """The table's entry for a method; ConfigError naming the known methods for any other name."""
    _load_plugins()
    entry = METHOD_TABLE.get(name)
    if entry is None:
        raise ConfigError(f"unknown method {name!r}; expected one of {', '.join(runnable_names())}")
    return entry


def filter_kind(name: str) -> str:
    """How the runner drives a method: 'dr', 'ckf', 'ackf' or 'detect' (ConfigError for an unknown name)."""
    return method(name).filter


def why_line(r: EpochResult, detector: object | None = None) -> str:
    """One line: the statistic `r.method` compared at this epoch, its threshold and the outcome.

    `detector` is the trained detector of the epoch's leader (None: only the
    result's score and threshold are shown).
    """
    if not math.isfinite(r.score):
        return "not judged (a feature is missing at this epoch)"
    entry = METHOD_TABLE.get(r.method)
    return (entry.why if entry is not None else generic_why)(r, detector)


def short_names(names: list[str]) -> str:
    """Methods by their short names, comma-separated (so an event line fits the viewer's panel)."""
    return ", ".join(METHOD_TABLE[n].short if n in METHOD_TABLE else n for n in names)
