"""The trial manifest (TOML): trial name and date, vehicles, roles and their logs.

See docs/design.md section 4. Every problem is reported as one
`ManifestError` naming the manifest, the vehicle and log concerned.

A log's table (`[[vehicles.logs]]`) takes `sensor`, `format`, `path` (a path,
a glob or a list), `source` (a live log), `prefix`, `order`, and for its clock
either `clock_offset_s` (seconds added to a UTC clock's times) or
`time_base = "sim"` / `"boot"` with `start = "2024-05-01T10:00:00Z"`, the UTC
instant of the log's time zero (a bag in simulated time; a dataflash log's
boot): docs/time-bases.md. Every other key is a format option.
"""

from __future__ import annotations

import itertools
import tomllib
from dataclasses import dataclass, field, replace
from datetime import date
from pathlib import Path, PurePosixPath
from typing import Any

from formats.rosbag import bag_folder

from .clock import RELATIVE_BASES, TIME_BASES, in_offset_window, parse_utc
from .manifest_checks import ValueProblem, check_log_paths, check_values, outside

ROLES = ("leader", "follower", "buoy")
SENSORS = ("gps", "dvl", "ins", "modem", "usbl")
# formats whose one file holds several sensors: their log entry needs no `sensor`
CONTAINER_FORMATS = ("rosbag", "alog", "mavlink")
ORDERS = ("name", "time")
_LOG_KEYS = {"sensor", "format", "path", "source", "clock_offset_s", "prefix", "order", "time_base", "start"}
_GLOB_CHARS = frozenset("*?[")
# a manifest is a small TOML file; one from another lab may be anything (a huge file, a device that never ends)
MAX_MANIFEST_BYTES = 4 << 20
# a glob's matches become one log's parts: more than this is a pattern that went wrong, not a rotated log
MAX_GLOB_MATCHES = 10_000


class ManifestError(ValueError):
    """A manifest that cannot be used, with a message naming the problem."""


@dataclass(frozen=True)
class LogSpec:
    """One log file of a vehicle: sensor family, vendor format, path and options."""

    vehicle: str
    sensor: str
    format: str
    path: str                       # relative to the manifest, POSIX separators
    clock_offset_s: float = 0.0
    prefix: str = "auto"
    options: dict[str, Any] = field(default_factory=dict)
    # a live source (`auvreplay capture`) instead of a file: serial://, udp://, tcp://, tcp-listen://, tail:
    source: str = ""
    # the files of a rotated or split log, relative like `path`; one log in this order (`order`:
    # "name" as listed or globbed, "time" sorted by content time when recording); () means just `path`
    parts: tuple[str, ...] = ()
    order: str = "name"
    # what the log's clock counts (recorders.clock, docs/time-bases.md): "utc", or "sim"/"boot" seconds from
    # a zero whose UTC instant is `start_ns`
    time_base: str = "utc"
    start_ns: int | None = None

    def files(self) -> tuple[str, ...]:
        """The log's files in manifest order: its parts, or its one path."""
        return self.parts or (self.path,)


@dataclass(frozen=True)
class Vehicle:
    """A vehicle (or buoy) of the trial with its role and modem address."""

    name: str
    role: str
    modem_address: int | None = None
    logs: tuple[LogSpec, ...] = ()


@dataclass(frozen=True)
class Manifest:
    """A parsed manifest; `root` is the directory that log paths are relative to."""

    path: Path
    root: Path
    name: str
    date: date | None
    vehicles: tuple[Vehicle, ...]
    text: str
    sound_speed_mps: float = 1500.0

    def address_book(self) -> dict[int, str]:
        """Modem address -> vehicle name."""
        return {v.modem_address: v.name for v in self.vehicles if v.modem_address is not None}

    def logs(self) -> list[LogSpec]:
        """Every log of every vehicle, in manifest order."""
        return [log for v in self.vehicles for log in v.logs]

    def role_of(self, vehicle: str) -> str:
        """The role of a named vehicle."""
        return next(v.role for v in self.vehicles if v.name == vehicle)


def _parse_date(value: Any, where: str) -> date | None:
    if value is None:
        return None
    if isinstance(value, date):
        return value
    try:
        return date.fromisoformat(str(value))
    except ValueError as exc:
        raise ManifestError(f"{where}: trial date {value!r} is not YYYY-MM-DD") from exc


def _parse_log(raw: Any, vehicle: str, index: int, where: str) -> LogSpec:
    label = f"{where}: vehicle {vehicle!r}, log {index + 1}"
    if not isinstance(raw, dict):
        raise ManifestError(f"{label}: expected a table")
    source = raw.get("source", "")
    if not isinstance(source, str):
        raise ManifestError(f"{label}: 'source' must be text such as udp://127.0.0.1:5000")
    if source and not raw.get("path"):  # a live log's name (in the archive, for unpack) when it gives none
        raw = {**raw, "path": f"{vehicle}/{raw.get('sensor')}.{raw.get('format')}"}
    paths = raw.get("path")
    if isinstance(paths, list) and paths and all(isinstance(p, str) and p for p in paths):
        raw = {**raw, "path": paths[0]}
        parts = tuple(str(PurePosixPath(p.replace("\\", "/"))) for p in paths)
    else:
        parts = ()
    container = raw.get("format") in CONTAINER_FORMATS
    if container and "sensor" in raw:
        raise ManifestError(f"{label} ({raw.get('path')}): a {raw['format']} log holds several sensors; "
                            "give it no 'sensor' (each message goes to its sensor's topic)")
    for key in ("format", "path") if container else ("sensor", "format", "path"):
        if not isinstance(raw.get(key), str) or not raw[key]:
            what = "a path, a glob or a list of paths" if key == "path" else f"'{key}'"
            raise ManifestError(f"{label}: missing or empty {what}")
    sensor = "" if container else raw["sensor"]
    if not container and sensor not in SENSORS:
        raise ManifestError(f"{label} ({raw['path']}): unknown sensor {sensor!r}; use one of {', '.join(SENSORS)}")
    order = raw.get("order", "name")
    if order not in ORDERS:
        raise ManifestError(f"{label} ({raw['path']}): order = {order!r}; use one of {', '.join(ORDERS)}")
    path = PurePosixPath(raw["path"].replace("\\", "/"))
    try:
        offset = float(raw.get("clock_offset_s", 0.0))
    except (TypeError, ValueError) as exc:
        raise ManifestError(f"{label} ({raw['path']}): clock_offset_s must be a number") from exc
    time_base, start_ns = _time_base(raw, offset, f"{label} ({raw['path']})")
    options = {k: v for k, v in raw.items() if k not in _LOG_KEYS}
    return LogSpec(vehicle, sensor, raw["format"], str(path), offset, str(raw.get("prefix", "auto")), options,
                   source, parts=parts, order=order, time_base=time_base, start_ns=start_ns)


def _time_base(raw: dict[str, Any], offset: float, label: str) -> tuple[str, int | None]:
    """A log's `time_base` and `start` (UTC ns), checked: a sim/boot clock needs its start, a UTC one has none."""
    base = raw.get("time_base", "utc")
    if base not in TIME_BASES:
        raise ManifestError(f"{label}: time_base = {base!r}; use one of {', '.join(TIME_BASES)}")
    if "start" not in raw:
        if base in RELATIVE_BASES:
            raise ManifestError(f"{label}: time_base = {base!r} needs start = \"YYYY-MM-DDTHH:MM:SSZ\", "
                                "the UTC instant of the log's time zero")
        return base, None
    start = parse_utc(raw["start"])
    if start is None:
        raise ManifestError(f"{label}: start = {raw['start']!r} is not an ISO 8601 UTC instant "
                            "such as \"2024-05-01T10:00:00Z\" (with its Z or UTC offset)")
    if not in_offset_window(start):
        raise ManifestError(f"{label}: start = {raw['start']!s} is outside 1980-01-01 .. 2100-01-01 UTC")
    if base not in RELATIVE_BASES:
        raise ManifestError(f"{label}: start places the zero of a clock that is not UTC: give it with "
                            "time_base = \"sim\" (a bag in simulated time) or \"boot\" (a dataflash log's "
                            "time since boot)")
    if offset:
        raise ManifestError(f"{label}: give start or clock_offset_s, not both (start already places the log in UTC)")
    return base, start


def _parse_vehicle(raw: Any, index: int, where: str) -> Vehicle:
    if not isinstance(raw, dict) or not isinstance(raw.get("name"), str) or not raw["name"]:
        raise ManifestError(f"{where}: vehicle {index + 1} has no name")
    name = raw["name"]
    if "/" in name or name.strip() != name:
        raise ManifestError(f"{where}: vehicle name {name!r} cannot contain '/' or surrounding spaces")
    role = raw.get("role", "")      # left out: the replay guesses it from the vehicle's sensors
    if role not in ROLES + ("",):
        raise ManifestError(f"{where}: vehicle {name!r} has role {role!r}; use one of {', '.join(ROLES)}, or leave "
                            "it out (a vehicle alone needs none)")
    address = raw.get("modem_address")
    if address is not None and (not isinstance(address, int) or isinstance(address, bool)):
        raise ManifestError(f"{where}: vehicle {name!r}: modem_address must be an integer")
    logs = tuple(_parse_log(lg, name, i, where) for i, lg in enumerate(raw.get("logs", [])))
    return Vehicle(name, role, address, logs)


def parse_manifest(text: str, path: Path) -> Manifest:
    """Parse and check manifest text; log paths are checked against `path`'s directory."""
    where = str(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ManifestError(f"{where}: not valid TOML ({exc})") from exc
    try:
        check_values(data, where)
    except ValueProblem as exc:
        raise ManifestError(str(exc)) from None
    trial = data.get("trial", {})
    if not isinstance(trial, dict):
        raise ManifestError(f"{where}: [trial] must be a table")
    vehicles = tuple(_parse_vehicle(v, i, where) for i, v in enumerate(data.get("vehicles", [])))
    if not vehicles:
        raise ManifestError(f"{where}: no [[vehicles]]")
    names = [v.name for v in vehicles]
    dup = {n for n in names if names.count(n) > 1}
    if dup:
        raise ManifestError(f"{where}: vehicle names used twice: {', '.join(sorted(dup))}")
    addresses = [v.modem_address for v in vehicles if v.modem_address is not None]
    if len(set(addresses)) != len(addresses):
        raise ManifestError(f"{where}: two vehicles share a modem address")
    manifest = Manifest(path, path.parent, str(trial.get("name", path.stem)), _parse_date(trial.get("date"), where),
                        vehicles, text, float(trial.get("sound_speed_mps", 1500.0)))
    _check_references(manifest, names)
    return manifest


def _check_references(manifest: Manifest, names: list[str]) -> None:
    """Vehicle names given in log options (target, source, node...) must exist."""
    for log in manifest.logs():
        for key in ("target", "source", "destination", "node", "leader"):
            ref = log.options.get(key)
            if isinstance(ref, str) and ref not in names:
                raise ManifestError(f"{manifest.path}: vehicle {log.vehicle!r}, log {log.path}: "
                                    f"{key} = {ref!r} is not a vehicle of this trial")


def load_manifest(path: str | Path, allow_outside: bool = False) -> Manifest:
    """Read and parse a manifest file; a missing file or log is a ManifestError.

    A log path that resolves outside the manifest's folder is a ManifestError
    too, unless `allow_outside`.
    """
    path = Path(path)
    if path.exists() and not path.is_file():   # a device, a FIFO (whose open would wait for a writer), a folder
        raise ManifestError(f"{path}: not a regular file, not a trial manifest")
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_MANIFEST_BYTES + 1)   # bounded: a special file or a huge one stops here
        if len(raw) > MAX_MANIFEST_BYTES:
            raise ManifestError(f"{path}: larger than {MAX_MANIFEST_BYTES >> 20} MiB, not a trial manifest")
        text = raw.decode("utf-8")
    except OSError as exc:
        raise ManifestError(f"{path}: cannot read manifest ({exc.strerror or exc})") from exc
    except UnicodeDecodeError as exc:
        raise ManifestError(f"{path}: manifest is not UTF-8 text") from exc
    manifest = parse_manifest(text, path)
    manifest = _expand_globs(manifest, allow_outside)
    manifest = _expand_bag_folders(manifest, allow_outside)
    try:   # every file a log names, a glob's matches included, must be inside the manifest's folder
        check_log_paths(manifest.root, [name for log in manifest.logs() for name in log.files()], str(path),
                        allow_outside)
        check_log_paths(manifest.root, [p for log in manifest.logs() for p in log.options.get("msg_paths", [])],
                        str(path), allow_outside)
    except ValueProblem as exc:
        raise ManifestError(str(exc)) from None
    for log in manifest.logs():
        for name in log.files():
            full = manifest.root / name
            if not log.source and not full.is_file():
                raise ManifestError(f"{path}: vehicle {log.vehicle!r}: log file {name} not found (looked in {full})")
        for name in log.options.get("msg_paths", []):
            if not (manifest.root / name).exists():
                raise ManifestError(f"{path}: vehicle {log.vehicle!r}: msg_paths: {name} not found "
                                    f"(looked in {manifest.root / name})")
    return manifest


def _expand_globs(manifest: Manifest, allow_outside: bool = False) -> Manifest:
    """Every log whose path is a glob gets its matching files as parts, in name order.

    Unless `allow_outside`, a glob may not climb out of the manifest's folder
    (an absolute pattern or a ".." part): it is refused before any directory
    outside is listed. At most MAX_GLOB_MATCHES files match.
    """
    vehicles = []
    for v in manifest.vehicles:
        logs = []
        for log in v.logs:
            if not log.source and not log.parts and _GLOB_CHARS & set(log.path):
                pattern = PurePosixPath(log.path.replace("\\", "/"))
                if not allow_outside and (pattern.is_absolute() or ".." in pattern.parts):
                    raise ManifestError(f"{manifest.path}: vehicle {v.name!r}: the glob {log.path} reaches outside "
                                        f"the manifest's folder (--allow-outside permits it)")
                # pathlib globs relative patterns only: an absolute one (allowed outside) from its anchor
                base, rel = (Path(pattern.anchor), pattern.relative_to(pattern.anchor).as_posix()) \
                    if pattern.is_absolute() else (manifest.root, log.path)
                matches = (p for p in base.glob(rel) if p.is_file())
                found = sorted(p.as_posix() if pattern.is_absolute() else p.relative_to(manifest.root).as_posix()
                               for p in itertools.islice(matches, MAX_GLOB_MATCHES + 1))
                if len(found) > MAX_GLOB_MATCHES:
                    raise ManifestError(f"{manifest.path}: vehicle {v.name!r}: the glob {log.path} matches more "
                                        f"than {MAX_GLOB_MATCHES} files")
                if not found:
                    raise ManifestError(f"{manifest.path}: vehicle {v.name!r}: no file matches {log.path} "
                                        f"(looked in {manifest.root})")
                log = replace(log, parts=tuple(found))
            logs.append(log)
        vehicles.append(replace(v, logs=tuple(logs)))
    return replace(manifest, vehicles=tuple(vehicles))


def _expand_bag_folders(manifest: Manifest, allow_outside: bool) -> Manifest:
    """Every rosbag log naming a ROS 2 bag folder (the folder, its metadata.yaml or a storage file in it) gets
    all the folder's files as parts: the bag is the folder (`ros2 bag` reads and writes it so), and the
    archive keeps every file of it, so that an unpacked archive gives a folder rosbags reopens."""
    vehicles = []
    for v in manifest.vehicles:
        logs = []
        for log in v.logs:
            if log.format == "rosbag" and not log.source and not log.parts:
                log = _bag_folder_log(manifest, v.name, log, allow_outside)
            logs.append(log)
        vehicles.append(replace(v, logs=tuple(logs)))
    return replace(manifest, vehicles=tuple(vehicles))


def _bag_folder_log(manifest: Manifest, vehicle: str, log: LogSpec, allow_outside: bool) -> LogSpec:
    full = manifest.root / log.path
    if not allow_outside and outside(manifest.root, log.path) is not None:
        return log   # refused with the other paths, before anything outside is listed
    folder = bag_folder(full)
    if folder is None:
        if full.is_dir():
            raise ManifestError(f"{manifest.path}: vehicle {vehicle!r}: {log.path}/ is a folder without "
                                "metadata.yaml, not a ROS 2 bag folder (name a ROS 1 .bag, or a bag folder)")
        return log
    files = sorted(p for p in itertools.islice(folder.iterdir(), MAX_GLOB_MATCHES + 1) if p.is_file())
    if len(files) > MAX_GLOB_MATCHES:
        raise ManifestError(f"{manifest.path}: vehicle {vehicle!r}: the bag folder {folder} holds more than "
                            f"{MAX_GLOB_MATCHES} files")
    given = PurePosixPath(log.path)
    base = given if full.is_dir() else given.parent   # as the manifest names it (relative, or outside if allowed)
    return replace(log, parts=tuple(str(base / p.name) for p in files))
