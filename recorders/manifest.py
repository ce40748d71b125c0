"""The trial manifest (TOML): trial name and date, vehicles, roles and their logs.

See DESIGN.md "The trial manifest". Every problem is reported as one
`ManifestError` naming the manifest, the vehicle and log concerned.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from datetime import date
from pathlib import Path, PurePosixPath
from typing import Any

from .manifest_checks import ValueProblem, check_log_paths, check_values

ROLES = ("leader", "follower", "buoy")
SENSORS = ("gps", "dvl", "ins", "modem", "usbl")
_LOG_KEYS = {"sensor", "format", "path", "source", "clock_offset_s", "prefix"}


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
    for key in ("sensor", "format", "path"):
        if not isinstance(raw.get(key), str) or not raw[key]:
            raise ManifestError(f"{label}: missing or empty '{key}'")
    if raw["sensor"] not in SENSORS:
        raise ManifestError(f"{label} ({raw['path']}): unknown sensor {raw['sensor']!r}; use one of {', '.join(SENSORS)}")
    path = PurePosixPath(raw["path"].replace("\\", "/"))
    try:
        offset = float(raw.get("clock_offset_s", 0.0))
    except (TypeError, ValueError) as exc:
        raise ManifestError(f"{label} ({raw['path']}): clock_offset_s must be a number") from exc
    options = {k: v for k, v in raw.items() if k not in _LOG_KEYS}
    return LogSpec(vehicle, raw["sensor"], raw["format"], str(path), offset, str(raw.get("prefix", "auto")), options,
                   source)


def _parse_vehicle(raw: Any, index: int, where: str) -> Vehicle:
    if not isinstance(raw, dict) or not isinstance(raw.get("name"), str) or not raw["name"]:
        raise ManifestError(f"{where}: vehicle {index + 1} has no name")
    name = raw["name"]
    if "/" in name or name.strip() != name:
        raise ManifestError(f"{where}: vehicle name {name!r} cannot contain '/' or surrounding spaces")
    role = raw.get("role")
    if role not in ROLES:
        raise ManifestError(f"{where}: vehicle {name!r} has role {role!r}; use one of {', '.join(ROLES)}")
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
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise ManifestError(f"{path}: cannot read manifest ({exc.strerror or exc})") from exc
    except UnicodeDecodeError as exc:
        raise ManifestError(f"{path}: manifest is not UTF-8 text") from exc
    manifest = parse_manifest(text, path)
    try:
        check_log_paths(manifest.root, [log.path for log in manifest.logs()], str(path), allow_outside)
    except ValueProblem as exc:
        raise ManifestError(str(exc)) from None
    for log in manifest.logs():
        full = manifest.root / log.path
        if not log.source and not full.is_file():
            raise ManifestError(f"{path}: vehicle {log.vehicle!r}: log file {log.path} not found (looked in {full})")
    return manifest
