"""Writing a run's results into MCAP: /replay/<run>/... channels and the `run` metadata record."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from formats import schemas as S
from formats.mcap_writer import ArchiveWriter
from formats.units import NS
from replay.events import (
    EpochResult,
    ErrorSample,
    Fix,
    Listener,
    RunResults,
    TrainedDetectors,
    UsblEpoch,
)
from replay.stack.methods import detecting_names
from replay.stack.model import offset_to_latlon

RAD = 180.0 / math.pi


def _cov_enu(nn: float, ne: float, ee: float) -> tuple[float, ...]:
    """ENU 3x3 (row-major) from north-east covariances; vertical unknown."""
    return (ee, ne, 0.0, ne, nn, 0.0, 0.0, 0.0, math.nan)


class ResultsWriter(Listener):
    """Streams a run's estimates, detections, ANFIS snapshots and USBL fixes to an archive."""

    def __init__(self, writer: ArchiveWriter, run_id: str, t0_ns: int):
        self.w, self.run, self.t0_ns = writer, run_id, t0_ns
        self._origin: tuple[float, float] | None = None
        self._detecting = detecting_names()
        self._fix_topics: set[str] = set()       # the estimate topics written once (channel registered)
        self._detection_topics: set[str] = set()  # likewise the detection topics
        self._estimate_topics: dict[str, dict[str, str]] = {}   # follower -> method -> its estimate topic

    def origin(self, lat_rad: float, lon_rad: float) -> None:
        self._origin = (lat_rad, lon_rad)

    def _ns(self, t_s: float) -> int:
        return self.t0_ns + round(t_s * NS)

    def estimates(self, follower: str, t_s: float, est: Mapping[str, tuple[float, ...]]) -> None:
        t = self._ns(t_s)
        tail = None
        topics = self._estimate_topics.get(follower)
        if topics is None:
            topics = self._estimate_topics[follower] = {}
        packed: dict[int, bytes] = {}     # methods with one state share one estimate tuple: its bytes made once
        for method, value in est.items():
            topic = topics.get(method)
            if topic is None:
                topic = topics[method] = f"/replay/{self.run}/{follower}/{method}"
            if topic not in self._fix_topics:     # the first fix of a topic registers its channel
                self._fix_topics.add(topic)
                lat, lon, nn, ne, ee = value
                fix = S.location_fix(t, follower, lat * RAD, lon * RAD, math.nan, _cov_enu(nn, ne, ee),
                                     S.COVARIANCE_KNOWN)
                self.w.write(topic, fix, t)
                continue
            # the same bytes without a message (once a second per method: a tenth of a replay's messages)
            data = packed.get(id(value))
            if data is None:
                if tail is None:
                    tail = S.location_fix_tail(t, follower)
                lat, lon, nn, ne, ee = value
                data = packed[id(value)] = S.location_fix_bytes(tail, t, follower, lat * RAD, lon * RAD, math.nan,
                                                                _cov_enu(nn, ne, ee), S.COVARIANCE_KNOWN)
            self.w.write_serialized(topic, data, t)

    def epoch(self, follower: str, results: list[EpochResult], leader_fix: Fix | None) -> None:
        t = self._ns(results[0].time_s)
        topic = f"/replay/{self.run}/{follower}/detections"
        stamp = None
        for r in results:
            if r.method not in self._detecting:
                continue
            scores = (float(r.score), float(r.threshold), float(r.f1), float(r.f2), float(r.f3))
            extra = tuple(float(getattr(r, name)) for name in S.DETECTION_EXTRA_NAMES)
            if topic not in self._detection_topics:     # the first detection registers its channel
                self._detection_topics.add(topic)
                self.w.write(topic, S.detection(t, follower, r.leader, r.method, bool(r.flagged), scores,
                                                int(r.label), bool(r.capped), extra), t)
                continue
            # the same bytes without a message (several a range epoch: most of the results archive's messages)
            if stamp is None:
                stamp = S.detection_stamp(t)
            self.w.write_serialized(topic, S.detection_bytes(stamp, t, follower, r.leader, r.method, bool(r.flagged),
                                                             scores, int(r.label), bool(r.capped), extra), t)

    def errors(self, follower: str, samples: list[ErrorSample]) -> None:
        pass  # errors are derived data: the metrics carry them

    def trained(self, follower: str, models: TrainedDetectors, t_s: float) -> None:
        t = self._ns(t_s)
        for method in self._detecting:
            per_leader = models.detectors(method)
            for leader, det in per_leader.items():
                if det is None or not hasattr(det, "snapshots"):
                    continue
                for snap in det.snapshots():
                    self.w.write(f"/replay/{self.run}/anfis/{leader}", snapshot_message(snap, t, leader, method), t)

    def usbl(self, epoch: UsblEpoch, positions: dict[str, tuple[float, float]]) -> None:
        origin = self._origin
        if origin is None:
            return
        t = self._ns(epoch.t_s)
        for method, (e, n) in positions.items():
            if not (math.isfinite(e) and math.isfinite(n)):
                continue
            cov = epoch.fix.covariance if method == "kmcdf2" else None
            cov_enu = _cov_enu(cov[1, 1], cov[0, 1], cov[0, 0]) if cov is not None else None
            lat, lon = offset_to_latlon(n, e, *origin)     # the inverse of how the engine made e, n
            fix = S.location_fix(t, epoch.target, lat * RAD, lon * RAD, math.nan,
                                 cov_enu, S.COVARIANCE_KNOWN if cov_enu else S.COVARIANCE_UNKNOWN)
            self.w.write(f"/replay/{self.run}/{epoch.target}/{method}", fix, t)

    def finished(self, follower: str, results: RunResults) -> None:
        pass


def snapshot_message(snap: Any, t_ns: int, leader: str, method: str) -> Any:
    """An auvreplay.AnfisSnapshot from a ModelSnapshot."""
    msg = S.AnfisSnapshot(time=S.timestamp(t_ns), leader=leader, epoch=int(snap.epoch),
                          training_rmse=float(snap.training_rmse), inputs=int(snap.a.shape[0]),
                          mfs_per_input=int(snap.mfs_per_input), rule_structure=snap.rule_structure,
                          threshold=float(snap.threshold), trainer=f"{method}:{snap.trainer}")
    for i in range(snap.a.shape[0]):
        for j in range(snap.a.shape[1]):
            msg.membership.add(input=i, index=j, a=float(snap.a[i, j]), b=float(snap.b[i, j]),
                               c=float(snap.c[i, j]))
    msg.consequents.extend(float(v) for v in snap.consequents.ravel())
    msg.input_min.extend(float(v) for v in snap.input_min)
    msg.input_max.extend(float(v) for v in snap.input_max)
    return msg
