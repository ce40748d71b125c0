"""Checks on a manifest from someone else's machine: every value in range, every log inside its folder.

A manifest travels with other people's logs, so it is untrusted input: a
`clock_offset_s = nan`, a `prefix = "weird"` or a path holding a NUL is one ManifestError line
naming the key and the value, and a log path that resolves (symlinks
followed) outside the manifest's folder is refused unless the user allows it.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

from formats.lines import PREFIX_STYLES

from .clock import MAX_OFFSET_S, NS, date_text

# (low, high) for numbers a manifest may give; the limits are physical (or the format's), never a tuning
RANGES: dict[str, tuple[float, float]] = {
    # about 133 years either way: a bag in simulated time needs ~1.7e9; whether the offset puts the log's
    # own times in 1980-2100 is checked when it is recorded (recorders.clock.offset_problem)
    "clock_offset_s": (-MAX_OFFSET_S, MAX_OFFSET_S),
    "sound_speed_mps": (1000.0, 2000.0),    # water: 1400-1600 m/s
    "uere_m": (1e-6, 1e4),
    "beam_angle_deg": (0.0, 90.0),
    "max_range_m": (1e-3, 1e7),
}
# any other number in a log's table must still be finite and of a sane size
ANY_NUMBER = 1e12
MODEM_ADDRESS = (0, 2**31 - 1)


class ValueProblem(ValueError):
    """A manifest value out of its range (the message names key and value)."""


def check_number(key: str, value: Any, label: str) -> None:
    """A number under `key` must be finite and within RANGES (or ANY_NUMBER); a bool is not a number."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        if key in RANGES:
            raise ValueProblem(f"{label}: {key} = {value!r} is not a number")
        return
    try:
        x = float(value)
    except OverflowError:
        raise ValueProblem(f"{label}: {key} = {value} is too large") from None
    low, high = RANGES.get(key, (-ANY_NUMBER, ANY_NUMBER))
    if not math.isfinite(x) or not low <= x <= high:
        # an offset's own date: where it puts a clock counting from 0 (a bag in simulated time)
        when = f": it puts time 0 of the log's clock at {date_text(x * NS)}" \
            if key == "clock_offset_s" and math.isfinite(x) else ""
        raise ValueProblem(f"{label}: {key} = {value!r} is out of range [{low:g}, {high:g}]{when}")


# a control character in a manifest string: NUL breaks every path call, a line break or an escape sequence
# breaks the one-line messages and the terminal; a tab stays allowed (a tab-separated log's `delimiter`)
_CONTROL = re.compile(r"[\x00-\x08\x0a-\x1f\x7f-\x9f]")


def check_strings(value: Any, key: str, where: str) -> None:
    """Every string of a parsed manifest, keys included, free of control characters; ValueProblem naming the key."""
    if isinstance(value, str):
        bad = _CONTROL.search(value)
        if bad is not None:
            raise ValueProblem(f"{where}: {key} holds a control character (U+{ord(bad.group()):04X}): refused")
    elif isinstance(value, dict):
        for k, v in value.items():
            name = f"{key}.{k}" if key else str(k)
            if _CONTROL.search(str(k)):
                raise ValueProblem(f"{where}: a key {name!r} holds a control character: refused")
            check_strings(v, name, where)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            check_strings(item, f"{key}[{i + 1}]", where)


def check_values(data: dict[str, Any], where: str) -> None:
    """Every value of a parsed manifest (tomllib's dict) in range, every string without control characters;
    raises ValueProblem naming key and value."""
    check_strings(data, "", where)
    trial = data.get("trial", {})
    if isinstance(trial, dict):
        for key in ("sound_speed_mps",):
            if key in trial:
                check_number(key, trial[key], f"{where}: [trial]")
    vehicles = data.get("vehicles", [])
    if not isinstance(vehicles, list):
        raise ValueProblem(f"{where}: vehicles must be an array of tables ([[vehicles]])")
    for i, v in enumerate(vehicles):
        if not isinstance(v, dict):
            continue
        label = f"{where}: vehicle {v.get('name', i + 1)!r}"
        address = v.get("modem_address")
        if isinstance(address, int) and not isinstance(address, bool) \
                and not MODEM_ADDRESS[0] <= address <= MODEM_ADDRESS[1]:
            raise ValueProblem(f"{label}: modem_address = {address} is out of range {list(MODEM_ADDRESS)}")
        logs = v.get("logs", [])
        if not isinstance(logs, list):
            raise ValueProblem(f"{label}: logs must be an array of tables ([[vehicles.logs]])")
        for k, log in enumerate(logs):
            if isinstance(log, dict):
                _check_log(log, f"{label}, log {k + 1}" + (f" ({log['path']})" if isinstance(log.get("path"), str)
                                                         else ""))


def _check_log(log: dict[str, Any], label: str) -> None:
    msg_paths = log.get("msg_paths", [])
    if not (isinstance(msg_paths, list) and all(isinstance(p, str) and p for p in msg_paths)):
        raise ValueProblem(f"{label}: msg_paths = {msg_paths!r} must be a list of paths to .msg or .idl files "
                           "(or folders of them)")
    prefix = log.get("prefix", "auto")
    if prefix not in PREFIX_STYLES:
        raise ValueProblem(f"{label}: prefix = {prefix!r} is not one of {', '.join(PREFIX_STYLES)}")
    for key, value in log.items():
        if isinstance(value, list):
            for item in value:
                check_number(key, item, label)
        else:
            check_number(key, value, label)


def outside(root: Path, path: str) -> Path | None:
    """Where `path` (relative to root) really is when that is outside `root` (symlinks followed), else None."""
    real_root = os.path.realpath(root)
    real = os.path.realpath(os.path.join(root, path))
    return Path(real) if os.path.commonpath([real_root, real]) != real_root else None


def check_log_paths(root: Path, paths: list[str], where: str, allow_outside: bool) -> None:
    """Every log path resolves inside `root`, unless `allow_outside`; raises ValueProblem naming the first."""
    if allow_outside:
        return
    for p in paths:
        real = outside(root, p)
        if real is not None:
            raise ValueProblem(f"{where}: log {p} resolves to {real}, outside the manifest's folder {root}; "
                               "refused (--allow-outside to read it)")
