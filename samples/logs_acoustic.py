"""Acoustic logs of the simulated trial: WHOI Micro-Modem ping exchanges and EvoLogics USBL fixes.

Neither format carries UTC time, so every line gets the ISO 8601 host
timestamp a data logger adds (`formats.lines` strips it on decoding).
"""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np

from formats.evologics import notifications as evologics
from formats.micromodem import sentences as micromodem
from formats.units import NS

from .simulator import SimulatedTrial
from .trajectories import interp_track

# USBL modem clocks count seconds from power-up, switched on before the trial
USBL_POWER_UP_BEFORE_S = 600.0
# the modem answers a ping command in about this long (CAMPC echo)
ECHO_DELAY_NS = 5_000_000


def iso(t_ns: int) -> str:
    """ISO 8601 UTC with microseconds and a Z, as the host prefixes and CSVs write it."""
    sec, rem = divmod(int(t_ns), NS)
    stamp = datetime.fromtimestamp(sec, tz=UTC).strftime("%Y-%m-%dT%H:%M:%S")
    return f"{stamp}.{rem // 1000:06d}Z"


def host(t_ns: int, line: str) -> str:
    """A log line with its host-timestamp prefix."""
    return f"{iso(t_ns)} {line}"


def _addresses(trial: SimulatedTrial) -> dict[str, int]:
    out = {v.name: v.modem_address for v in trial.vehicles}
    out.update({b.name: b.modem_address for b in trial.buoys})
    return out


def _follower_lines(trial: SimulatedTrial, name: str) -> list[tuple[int, str]]:
    """Ping exchanges of a follower: command, echo and (unless dropped) the reply."""
    addr = _addresses(trial)
    c = trial.scenario.ranging.sound_speed_mps
    r, p = trial.ranges, trial.pings
    measured = {(round(float(t), 3), str(ld)): float(x)
                for t, f, ld, x in zip(r.t_s, r.follower, r.leader, r.range_m) if f == name}
    out: list[tuple[int, str]] = []
    for t, f, leader, replied in zip(p.t_s, p.follower, p.leader, p.replied):
        if f != name:
            continue
        t_ns = int(trial.t_ns(t))
        src, dst = addr[name], addr[str(leader)]
        if replied:
            owtt = measured[(round(float(t), 3), str(leader))] / c
            lines = micromodem.ping_exchange_lines(t_ns, src, dst, owtt)
            out += [(t_ns, line) for line in lines]
        else:
            # nobody answered: the command and its echo, nothing else
            t_cmd = t_ns - int(round(1e9 * _true_range(trial, name, str(leader), float(t)) / c))
            out.append((t_cmd, micromodem.host_line(t_cmd, micromodem.encode_ccmpc(src, dst))))
            out.append((t_cmd, micromodem.host_line(t_cmd + ECHO_DELAY_NS, micromodem.encode_campc(src, dst))))
    return out


def _true_range(trial: SimulatedTrial, follower: str, leader: str, t: float) -> float:
    a = interp_track(trial.vehicle(follower).track, np.array([t]))
    b = interp_track(trial.vehicle(leader).track, np.array([t]))
    return float(math.hypot(a["east_m"][0] - b["east_m"][0], a["north_m"][0] - b["north_m"][0]))


def _leader_lines(trial: SimulatedTrial, name: str) -> list[tuple[int, str]]:
    """Pings a leader's modem heard (and answered): $CAMPA at the reply instant."""
    addr = _addresses(trial)
    p = trial.pings
    out = []
    for t, f, leader, replied in zip(p.t_s, p.follower, p.leader, p.replied):
        if leader == name and replied:
            t_ns = int(trial.t_ns(t))
            out.append((t_ns, micromodem.host_line(t_ns, micromodem.encode_campa(addr[str(f)], addr[name]))))
    return out


def micromodem_log(trial: SimulatedTrial, name: str) -> bytes:
    """A vehicle's Micro-Modem log (host-timestamped NMEA), in the order the lines were written."""
    role = trial.vehicle(name).role
    entries = _follower_lines(trial, name) if role == "follower" else _leader_lines(trial, name)
    return "".join(line for _, line in entries).encode("ascii")


def evologics_usbl(trial: SimulatedTrial, name: str) -> bytes:
    """A buoy's USBL log: USBLLONG (position from its measured delay and phases) and USBLPHYD."""
    u = trial.usbl
    j = u.nodes.index(name)
    target_addr = _addresses(trial)[u.target]
    carrier = trial.scenario.usbl.frequency_hz
    rng_m = u.delay_s[:, j] * u.sound_speed_mps
    cx = np.clip(u.phase_x_rad[:, j] / u.kappa_d0_rad, -1.0, 1.0)
    cy = np.clip(u.phase_y_rad[:, j] / u.kappa_d0_rad, -1.0, 1.0)
    # the target (near the surface) is above the node: the vertical cosine is positive
    cz = np.sqrt(np.maximum(1.0 - cx**2 - cy**2, 0.0))
    heard = u.t_s + u.delay_true_s[:, j]
    lines = []
    for i in range(len(u.t_s)):
        t_ns = int(trial.t_ns(heard[i]))
        clock = round(float(heard[i]) + USBL_POWER_UP_BEFORE_S, 6)
        e, n, up = (float(rng_m[i] * c) for c in (cx[i], cy[i], cz[i]))
        long_line = evologics.encode_usbllong(
            target_addr, e, n, up, float(u.delay_s[i, j]), current_time_s=clock + 0.02,
            measurement_time_s=clock, accuracy_m=0.3)
        phyd = evologics.encode_usblphyd(target_addr, float(u.phase_x_rad[i, j]), float(u.phase_y_rad[i, j]),
                                         carrier, current_time_s=clock + 0.03, measurement_time_s=clock)
        lines.append(host(t_ns + 20_000_000, long_line))
        lines.append(host(t_ns + 30_000_000, phyd))
    return "".join(lines).encode("ascii")
