"""The engine's block path: a window of INS, DVL and GPS samples taken as columns, as the messages one by one.

`Engine.push(topic, t, msg)` does, per message, the intake (tracks, heading
and depth, DR and GPS events queued, positions to listeners) and then a
release of the followers' queues `lag_s` behind the stream. Most messages
release nothing, and most are INS samples whose intake is a few appends.
`push_block` does the intake of a whole `formats.mcap_blocks.MessageBlock`
with numpy and runs a release only at the messages where the per-message
path would release something: where a queued event falls due, where a USBL
epoch would close or be positioned, and at every message of another kind
(a range, a USBL observation, a diagnostic, another position source), which
goes through `Engine.push` itself. Between those stops nothing is read:
tracks take the block's rows tagged with their message number and a lookup
sees only the rows the stream has reached (`replay.engine.tracks.Horizon`),
DR events are computed from the block's columns with the heading and depth of
the INS sample before each DVL sample in stream order (`FollowerPipeline.
dr_payload`, the same rule) and queued in stream order. So every runner call,
every result, count and metric is the per-message path's, bit for bit
(tests/test_engine_blocks.py runs both). With one follower and messages in
order, the releases that only move its dead reckoning (DR and GPS events, no
range or fix due, the training at t_a said) go as one release at the last of
them (`_merged_release`): the same events in the same order. Listeners hear the same calls in the
same order, but for positions: a block's positions of one vehicle and source
come as columns (`Listener.positions`) once the block is done (those before
the trial's origin before it is said).

The per-message path stays: the online engine (capture) and `--rate` pacing
push message by message, and it is the reference of the tests.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from typing import TYPE_CHECKING, Any

import numpy as np

from formats.mcap_blocks import MessageBlock
from formats.units import NS
from replay.events import Fix

if TYPE_CHECKING:
    from replay.engine.core import Engine

DEG = math.pi / 180.0
_EXACT_NS = 1 << 53     # ns offsets below this convert to float exactly: numpy's t_s is Python's


def push_block(engine: Engine, block: MessageBlock) -> None:
    """Feed one block (its messages in stream order) as `Engine.push` would, message by message."""
    n = len(block)
    if not n:
        return
    off = block.log_ns - engine.t0_ns
    if np.abs(off).max() >= _EXACT_NS:
        t = np.array([(int(x) - engine.t0_ns) / NS for x in block.log_ns.tolist()])
    else:
        t = off / NS
    seq0 = engine.messages
    prev_last = engine.last_s
    last = np.maximum.accumulate(np.concatenate(([prev_last], t)))
    before = last[:-1]
    last = last[1:]
    until = last - engine._lag_s

    kinds = _kinds(engine, block)
    if kinds is None:
        for j in range(n):       # a block the columns cannot take: message by message
            topic = block.topics[block.topic_index[j]]
            engine.push(topic, int(block.log_ns[j]), block.message(topic, int(block.row[j])))
        return
    ti = block.topic_index
    kind_of = np.array([k for k, _ in kinds])[ti]
    # the messages after which Engine.push releases: every one with a handler (a diagnostic or a topic it
    # passes over returns before the release)
    handled = (kind_of != "skip") & (kind_of != "diagnostics")
    special_at = np.flatnonzero((kind_of == "special") | (kind_of == "diagnostics")).tolist()
    late = int(np.count_nonzero((t < before) & (kind_of != "special") & (kind_of != "diagnostics")))
    if late:
        engine.counts["out_of_order_messages"] += late

    # the rows of each columnar topic: stream positions, times, columns
    rows: dict[str, tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]] = {}
    for i, topic in enumerate(block.topics):
        if kinds[i][0] in ("ins", "gps", "dvl"):
            where = np.flatnonzero(ti == i)
            rows[topic] = (where, t[where], block.columns[topic])

    events: list[tuple[int, float, Any, str, tuple[Any, ...]]] = []   # (stream index, t, pipe, kind, payload)
    positions: list[tuple[str, str, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    origin_at = _origin_candidate(engine, block, kinds, rows)
    finals: dict[str, tuple[np.ndarray, ...]] = {}
    for i, topic in enumerate(block.topics):
        kind, vehicle = kinds[i]
        if kind not in ("ins", "gps", "dvl"):
            continue
        assert vehicle is not None
        where, ts, cols = rows[topic]
        if kind == "ins":
            lat, lon = cols["latitude"], cols["longitude"]
            ok = np.isfinite(lat) & np.isfinite(lon)
            depth = cols["depth_m"]
            fixed = np.where(np.isfinite(depth), depth, 0.0)
            w = where[ok]
            engine.tracks[vehicle].ins.extend(ts[ok], lat[ok] * DEG, lon[ok] * DEG, fixed[ok], seq0 + w + 1.0)
            positions.append((vehicle, "ins", w, ts[ok], lat[ok] * DEG, lon[ok] * DEG, fixed[ok]))
        elif kind == "gps":
            lat, lon = cols["latitude"], cols["longitude"]
            ok = np.isfinite(lat) & np.isfinite(lon)
            if not ok.all():
                engine.counts["gps_without_position"] += int(np.count_nonzero(~ok))
            w = where[ok]
            la, lo, zero = lat[ok] * DEG, lon[ok] * DEG, np.zeros(int(ok.sum()))
            engine.tracks[vehicle].gps.extend(ts[ok], la, lo, zero, seq0 + w + 1.0)
            positions.append((vehicle, "gps", w, ts[ok], la, lo, zero))
            pipe = engine.followers.get(vehicle)
            if pipe is not None:
                for k, a, b, c in zip(w.tolist(), ts[ok].tolist(), la.tolist(), lo.tolist()):
                    events.append((k, a, pipe, "gps", (Fix(a, b, c, 0.0),)))
    for vehicle, pipe in engine.followers.items():
        events.extend(_dr_events(pipe, f"/{vehicle}/ins", f"/{vehicle}/dvl", rows, kinds, block, finals))
    events.sort(key=lambda e: e[0])

    # where each event falls due: the first handled message at or after it whose release reaches its time
    hpos = np.flatnonzero(handled)
    huntil = until[hpos]
    h_list, hu_list = hpos.tolist(), huntil.tolist()
    stops: list[int] = []
    if events:
        at = np.array([e[0] for e in events])
        et = np.array([e[1] for e in events])
        p = np.maximum(np.searchsorted(hpos, at, "left"), np.searchsorted(huntil, et, "left"))
        stops = sorted({h_list[x] for x in p.tolist() if x < len(h_list)})

    usbl_before = None
    if engine._feeding:
        usbl_before = np.minimum(until, last - engine.config.engine.usbl_group_s)[hpos].tolist()
    else:
        usbl_before = (until - 1.0)[hpos].tolist()

    def next_release(k: int) -> int:
        """The first handled message >= k where a release does something (n: none in this block)."""
        best = n
        lo = bisect_left(h_list, k)
        for pipe in engine._pipes_only:
            head = pipe.queue_head_s()
            if head < math.inf:
                x = max(lo, bisect_left(hu_list, head))
                if x < len(h_list):
                    best = min(best, h_list[x])
        usbl = engine._usbl
        if usbl is not None:
            if usbl._earliest < math.inf:
                x = max(lo, bisect_right(usbl_before, usbl._earliest))
                if x < len(h_list):
                    best = min(best, h_list[x])
            if engine._feeding and usbl._closed_earliest < math.inf:
                x = max(lo, bisect_left(hu_list, usbl._closed_earliest))
                if x < len(h_list):
                    best = min(best, h_list[x])
        return best

    k = 0            # the next message to take in
    e = 0            # the next event to queue
    s = 0            # the next special message
    d = 0            # the next static stop
    origin_done = origin_at is None
    horizon = engine.horizon
    last_l, until_l = last.tolist(), until.tolist()     # per release: floats, not numpy scalars
    # a follower's heading and depth matter until its runner starts (_set_state): once all have, no call
    starting = any(pipe.runner is None for pipe in engine._pipes_only)
    # releases that only move one follower's dead reckoning may go as one (_merged_release): not with messages
    # out of order, whose events would be queued after later ones were released
    mergeable = not late and len(engine._pipes_only) == 1
    try:
        while k < n:
            while d < len(stops) and stops[d] < k:
                d += 1
            j = min(special_at[s] if s < len(special_at) else n, stops[d] if d < len(stops) else n,
                    next_release(k))
            if not origin_done and origin_at is not None and origin_at[0] <= j and engine._origin is None:
                # the origin is set while taking in its message: the events before it are queued first
                e = _queue_events(events, e, origin_at[0] - 1)
                _deliver(engine, positions, origin_at, before=True)
                engine._set_origin(*origin_at[1])
                origin_done = True
            if j >= n:
                e = _queue_events(events, e, n)
                break
            if s < len(special_at) and special_at[s] == j:
                e = _queue_events(events, e, j - 1)
                engine.messages = seq0 + j
                engine.last_s = float(before[j])
                horizon.seq = seq0 + j + 1
                _set_state(engine, finals, j - 1)
                msg_topic = block.topics[ti[j]]
                engine.push(msg_topic, int(block.log_ns[j]), block.message(msg_topic, int(block.row[j])))
                s += 1
                k = j + 1
                continue
            if mergeable and not starting and engine._usbl is None and engine._origin is not None:
                j = _merged_release(engine, j, h_list, hu_list, special_at[s] if s < len(special_at) else n)
            e = _queue_events(events, e, j)
            engine.messages = seq0 + j + 1
            engine.last_s = last_l[j]
            horizon.seq = seq0 + j + 1
            if starting:
                _set_state(engine, finals, j, always=False)
            engine._release(until_l[j])
            if starting:
                starting = any(pipe.runner is None for pipe in engine._pipes_only)
            k = j + 1
    finally:
        horizon.seq = math.inf
    engine.messages = seq0 + n
    engine.last_s = float(last[-1])
    _set_state(engine, finals, n - 1)
    _deliver(engine, positions, origin_at, before=False)


def _merged_release(engine: Engine, j: int, h_list: list[int], hu_list: list[float], special: int) -> int:
    """The last handled message (j or later) whose release stands for every release from j to it: the DR and GPS
    events falling due there, queued and released in time order, are those the releases one by one would
    release in the same order, and nothing between reads what the intake of those messages changes.

    So: one follower, started, no USBL, messages in order (the caller's conditions); before the next message
    that goes through `Engine.push` (`special`); before any queued range or fix, which reads the tracks as
    of its release; and before t_a until the detectors' training was said (it is said after its release).
    """
    pipe = engine._pipes_only[0]
    runner = pipe.runner
    assert runner is not None
    limit = pipe.first_epoch_s()
    if pipe.plan.name not in engine._trained:
        limit = min(limit, math.nextafter(runner.training_end_s, math.inf))
    x = min(bisect_left(hu_list, limit), bisect_left(h_list, special)) - 1
    return h_list[x] if x >= 0 and h_list[x] > j else j


def _queue_events(events: list[tuple[int, float, Any, str, tuple[Any, ...]]], e: int, upto: int) -> int:
    """Queue the events of messages <= upto, in stream order; the index of the next one."""
    while e < len(events) and events[e][0] <= upto:
        _, t_s, pipe, kind, payload = events[e]
        pipe.push_event(t_s, kind, payload)
        e += 1
    return e


def _origin_candidate(engine: Engine, block: MessageBlock, kinds: list[tuple[str, str | None]],
                      rows: dict[str, tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]]
                      ) -> tuple[int, tuple[float, float], bool] | None:
    """(stream index, origin, said after its own position) of the message that sets the origin in this block."""
    if engine._origin is not None:
        return None
    best: tuple[int, tuple[float, float], bool] | None = None
    for i, topic in enumerate(block.topics):
        kind = kinds[i][0]
        if kind == "gps" or (kind == "ins" and not engine._has_gps):
            where, _, cols = rows[topic]
            ok = np.flatnonzero(np.isfinite(cols["latitude"]) & np.isfinite(cols["longitude"]))
            if ok.size and (best is None or where[ok[0]] < best[0]):
                r = int(ok[0])
                best = (int(where[r]), (float(cols["latitude"][r] * DEG), float(cols["longitude"][r] * DEG)),
                        kind == "gps")
    return best


def _kinds(engine: Engine, block: MessageBlock) -> list[tuple[str, str | None]] | None:
    """Per topic index (kind, vehicle): "ins", "gps", "dvl" (taken as columns), "special" (through Engine.push),
    "diagnostics" (likewise, without a release) or "skip"; None when the block must go message by message."""
    kinds: list[tuple[str, str | None]] = []
    for topic in block.topics:
        route = engine._routes.get(topic)
        if route is None:
            route = engine._routes[topic] = engine._route(topic)
        vehicle, handler = route
        name = getattr(handler, "__name__", "")
        if vehicle is None or handler is None:
            kinds.append(("diagnostics" if topic == "/diagnostics" else "skip", vehicle))
        elif name in ("_ins", "_gps", "_dvl"):
            if topic not in block.columns:
                return None     # a track or DVL topic without columns: its rows would not be tagged
            kinds.append((name[1:], vehicle))
        else:
            # another position source sets the origin of a trial without GPS: message by message then
            if engine._origin is None and not engine._has_gps and topic in engine.layout.sources:
                return None
            kinds.append(("special", vehicle))
    return kinds


def _deliver(engine: Engine, positions: list[tuple[str, str, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                   np.ndarray]],
             origin_at: tuple[int, tuple[float, float], bool] | None, before: bool) -> None:
    """Positions to the listeners: those said before the origin (`before`), or the rest."""
    if not engine._hear_positions:
        return
    for vehicle, source, where, ts, lat, lon, depth in positions:
        if origin_at is None:
            sel = slice(None) if not before else slice(0)
        else:
            # the GPS fix that sets the origin is heard before it; an INS position that does, after it
            cut = origin_at[0] + (1 if origin_at[2] else 0)
            m = int(np.searchsorted(where, cut, "left"))
            sel = slice(0, m) if before else slice(m, None)
        if ts[sel].size:
            for listener in engine._hear_positions:
                listener.positions(vehicle, source, ts[sel], lat[sel], lon[sel], depth[sel])


def _dr_events(pipe: Any, ins_topic: str, dvl_topic: str,
               rows: dict[str, tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]],
               kinds: list[tuple[str, str | None]], block: MessageBlock,
               finals: dict[str, tuple[np.ndarray, ...]]) -> list[tuple[int, float, Any, str, tuple[Any, ...]]]:
    """A follower's DR events of the block, each DVL sample with the INS heading and depth before it."""
    ins = rows.get(ins_topic)
    if ins is not None:
        where, ts, cols = ins
        hok = np.isfinite(cols["heading_deg"])
        dok = np.isfinite(cols["depth_m"])
        h_at, h_t, h_v = where[hok], ts[hok], cols["heading_deg"][hok]
        d_at, d_v = where[dok], cols["depth_m"][dok]
    else:
        h_at = h_t = h_v = d_at = d_v = np.empty(0)
    finals[pipe.plan.name] = (h_at, h_t, h_v, d_at, d_v)
    dvl = rows.get(dvl_topic)
    if dvl is None:
        return []
    where, ts, cols = dvl
    hi = np.searchsorted(h_at, where, "left") - 1
    di = np.searchsorted(d_at, where, "left") - 1
    h_t_l, h_v_l, d_v_l = h_t.tolist(), h_v.tolist(), d_v.tolist()
    head0, depth0 = pipe._heading, pipe._depth
    out = []
    valid, vx, vy, frame = (cols[k].tolist() for k in ("valid", "velocity_x_mps", "velocity_y_mps", "frame"))
    for r, (at, t_s, h, dd) in enumerate(zip(where.tolist(), ts.tolist(), hi.tolist(), di.tolist())):
        heading = (h_t_l[h], h_v_l[h]) if h >= 0 else head0
        depth = d_v_l[dd] if dd >= 0 else depth0
        payload = pipe.dr_payload(t_s, valid[r], vx[r], vy[r], frame[r], heading, depth)
        if payload is not None:
            out.append((at, t_s, pipe, "dr", payload))
    return out


def _set_state(engine: Engine, finals: dict[str, tuple[np.ndarray, ...]], upto: int, always: bool = True) -> None:
    """Each follower's last INS heading and depth as of message `upto` (a runner's start reads the depth)."""
    for name, (h_at, h_t, h_v, d_at, d_v) in finals.items():
        pipe = engine.followers[name]
        if not always and pipe.runner is not None:
            continue
        h = int(np.searchsorted(h_at, upto, "right")) - 1 if h_at.size else -1
        if h >= 0:
            pipe._heading = (float(h_t[h]), float(h_v[h]))
        dd = int(np.searchsorted(d_at, upto, "right")) - 1 if d_at.size else -1
        if dd >= 0:
            pipe._depth = float(d_v[dd])
