"""The cooperative-localization methods by name: what filter each runs and which detector it uses.

A plain typed mapping (STYLE.md convention 3) of a factory per detecting method.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from types import MappingProxyType

from replay.stack.config import ALL_METHODS, DETECTING_METHODS, ConfigError, StackConfig
from replay.stack.detectors.anfis_detector import AnfisDetector
from replay.stack.detectors.anfis_hybrid import HybridAnfisDetector
from replay.stack.detectors.base import Detector
from replay.stack.detectors.chi_square import ChiSquareDetector
from replay.stack.detectors.cusum import CusumDriftDetector
from replay.stack.detectors.drift_reference import DriftReferenceDetector
from replay.stack.detectors.dual_threshold import DualThresholdDetector

DetectorFactory = Callable[[StackConfig], Detector]

FILTER_KINDS: Mapping[str, str] = MappingProxyType({
    "dead_reckoning": "dr",      # dead reckoning only, never updated by ranges
    "ckf": "ckf",                # CKF, every range used, no detection
    "ackf": "ackf",              # adaptive CKF, every range used, no detection
    **{name: "detect" for name in DETECTING_METHODS},   # ACKF with detection and isolation
})
"""Method name -> filter kind: 'dr', 'ckf', 'ackf' or 'detect'."""


def _anfis_hybrid(config: StackConfig) -> Detector:
    """A fresh HybridAnfisDetector."""
    return HybridAnfisDetector(config)


def _anfis(trainer: str, compensation: bool) -> DetectorFactory:
    """A factory building an AnfisDetector for one trainer and mode."""
    def build(config: StackConfig) -> Detector:
        """A fresh AnfisDetector for this trainer and mode."""
        return AnfisDetector(config, trainer=trainer, compensation=compensation)
    return build


DETECTOR_FACTORIES: Mapping[str, DetectorFactory] = MappingProxyType({
    "chi_square": ChiSquareDetector,
    "dual_threshold": DualThresholdDetector,
    "anfis": _anfis("hybrid", False),
    "anfis_aqpso": _anfis("aqpso_ga", False),
    "anfis_compensation": _anfis("hybrid", True),
    "cusum_drift": CusumDriftDetector,
    "anfis_hybrid": _anfis_hybrid,
    "drift_reference": DriftReferenceDetector,
})
"""Detecting method name -> factory(config) -> a fresh, untrained Detector."""


def filter_kind(method: str) -> str:
    """The filter kind of a method name; ValueError for a name not in config.ALL_METHODS."""
    if method not in FILTER_KINDS:
        raise ConfigError(f"unknown method {method!r}; expected one of {', '.join(ALL_METHODS)}")
    return FILTER_KINDS[method]
