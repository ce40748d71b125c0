"""Reading a run's configuration: a TOML file over the defaults (docs/design.md sections 7-14), `--set key=value`
overrides, run ids.

The configuration itself (`RunConfig`, `EngineConfig`) is in `replay.engine.config`, where the
engine may import it.

A run is a pure function of (archive, configuration): the run id is a hash of
the input's sha256, the canonical configuration and the package version, so
a changed parameter gives a new run id.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import tomllib
import types
import typing
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from replay.engine.config import USBL_UPDATE_METHODS, EngineConfig, RunConfig
from replay.errors import UserError
from replay.run.config_ranges import check_ranges
from replay.stack.config import CHOICES
from replay.stack.methods import runnable_names


def to_dict(cfg: Any) -> dict[str, Any]:
    """Nested plain dict (tuples as lists) of a configuration dataclass."""
    return json.loads(json.dumps(dataclasses.asdict(cfg)))


def canonical_json(cfg: RunConfig) -> str:
    """Canonical JSON text of a configuration (sorted keys, no spaces)."""
    return json.dumps(to_dict(cfg), sort_keys=True, separators=(",", ":"))


def run_id(cfg: RunConfig, input_sha256: str, version: str) -> str:
    """A short id that changes with the input, any parameter, or the package version."""
    h = hashlib.sha256(f"{input_sha256}\n{canonical_json(cfg)}\n{version}".encode())
    return h.hexdigest()[:12]


def _coerce(value: Any, hint: Any, key: str) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    try:
        if isinstance(value, str) and hint is not str and origin is None:
            value = json.loads(value) if hint is not bool else value.lower() in ("1", "true", "yes", "on")
        if hint is float:
            return float(value)
        if hint is int:
            if isinstance(value, float) and not value.is_integer():
                raise ValueError
            return int(value)
        if hint is bool:
            return bool(value)
        if hint is str:
            return str(value)
        optional_tuple = origin in (typing.Union, types.UnionType) and any(typing.get_origin(a) is tuple for a in args)
        if origin is tuple or optional_tuple:
            if value is None:
                return None
            if isinstance(value, str):
                value = [v for v in value.replace("[", "").replace("]", "").split(",") if v.strip()]
            inner = next((a for a in args if typing.get_origin(a) is tuple), hint)
            inner_args = typing.get_args(inner)
            elem = inner_args[0] if inner_args else str
            return tuple(_coerce(v, elem, key) for v in value)
    except (ValueError, TypeError, json.JSONDecodeError) as exc:
        raise UserError(f"configuration {key}: {value!r} is not a valid {getattr(hint, '__name__', hint)}") from exc
    return value


def config_from_parameters(params: dict[str, Any]) -> RunConfig:
    """The RunConfig a run's stored `parameters` (its `to_dict`) describe, over today's defaults; every
    value range-checked (replay.run.config_ranges), as a results archive may come from anyone."""
    if not isinstance(params, dict):
        raise UserError(f"configuration: expected a table of parameters, not {type(params).__name__}")
    return check_ranges(_apply(RunConfig(), params, ""))


def _apply(obj: Any, updates: dict[str, Any], prefix: str) -> Any:
    hints = typing.get_type_hints(type(obj))
    changes: dict[str, Any] = {}
    for key, value in updates.items():
        name = f"{prefix}{key}"
        if key not in hints:
            known = ", ".join(sorted(hints))
            raise UserError(f"configuration: unknown key {name!r} (known at this level: {known})")
        current = getattr(obj, key)
        if dataclasses.is_dataclass(current):
            if not isinstance(value, dict):
                raise UserError(f"configuration {name}: expected a table")
            changes[key] = _apply(current, value, f"{name}.")
        else:
            changes[key] = _coerce(value, hints[key], name)
    return dataclasses.replace(obj, **changes)


def _nest(dotted: str, value: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    node = out
    parts = dotted.split(".")
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    node[parts[-1]] = value
    return out


def _route(key: str) -> str:
    """Keys may omit their section: 'r_m' means 'stack.r_m', 'lag_s' means 'engine.lag_s'."""
    head = key.split(".")[0]
    if head in ("stack", "engine"):
        return key
    if head in {f.name for f in dataclasses.fields(EngineConfig)}:
        return f"engine.{key}"
    return f"stack.{key}"


def load_config(path: str | Path | None = None, overrides: Sequence[str] = (),
                window: tuple[float, float] | None = None, rate: float | None = None,
                default_methods: Sequence[str] | None = None) -> RunConfig:
    """Defaults, then the TOML file, then each `key=value` override, then the window and rate options.

    `default_methods` replaces the default method list (`evaluate` and `demo` run every method); a
    `methods` key in the file or an override still decides.
    """
    cfg = RunConfig()
    if default_methods is not None:
        cfg = dataclasses.replace(cfg, stack=dataclasses.replace(cfg.stack, methods=tuple(default_methods)))
    if path is not None:
        try:
            data = tomllib.loads(Path(path).read_text())
        except OSError as exc:
            raise UserError(f"{path}: cannot read configuration ({exc.strerror or exc})") from exc
        except tomllib.TOMLDecodeError as exc:
            raise UserError(f"{path}: not valid TOML ({exc})") from exc
        routed: dict[str, Any] = {}
        for key, value in data.items():
            if key in ("stack", "engine"):
                routed.setdefault(key, {}).update(value)
            else:
                _merge(routed, _nest(_route(key), value))
        cfg = _apply(cfg, routed, "")
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set {item!r}: expected key=value")
        cfg = _apply(cfg, _nest(_route(key.strip()), value.strip()), "")
    if window is not None:
        window_s = (float(window[0]), float(window[1]))
        cfg = dataclasses.replace(cfg, engine=dataclasses.replace(cfg.engine, window_s=window_s))
    if rate is not None:
        cfg = dataclasses.replace(cfg, engine=dataclasses.replace(cfg.engine, rate=rate))
    w = cfg.engine.window_s
    if w is not None and not (len(w) == 2 and math.isfinite(w[0]) and math.isfinite(w[1]) and w[0] < w[1]):
        raise UserError(f"window {list(w)}: expected two finite times T0 < T1 (seconds from the trial start)")
    if not (math.isfinite(cfg.engine.rate) and cfg.engine.rate >= 0):
        raise UserError(f"rate {cfg.engine.rate}: expected >= 0 (0 = as fast as possible)")
    known = runnable_names()
    bad = [m for m in cfg.stack.methods if m not in known]
    if bad:
        raise UserError(f"configuration methods: unknown {', '.join(bad)} (known: {', '.join(known)})")
    for key, allowed in CHOICES.items():
        value = functools.reduce(getattr, key.split("."), cfg)
        if value not in allowed:
            raise UserError(f"configuration {key}: unknown {value!r} (known: {', '.join(allowed)})")
    if cfg.engine.usbl_update not in ("",) + USBL_UPDATE_METHODS:
        raise UserError(f"configuration engine.usbl_update: unknown {cfg.engine.usbl_update!r} "
                        f"(known: {', '.join(USBL_UPDATE_METHODS)}, or empty for none)")
    if cfg.engine.usbl_update and not cfg.engine.kmcdf:
        raise UserError("configuration engine.usbl_update needs engine.kmcdf = true (USBL epochs positioned)")
    if cfg.engine.usbl_update and not cfg.engine.usbl_update_sigma_m > 0:
        raise UserError("configuration engine.usbl_update_sigma_m: must be > 0")
    return check_ranges(cfg)


def _merge(into: dict[str, Any], new: dict[str, Any]) -> None:
    for k, v in new.items():
        if isinstance(v, dict) and isinstance(into.get(k), dict):
            _merge(into[k], v)
        else:
            into[k] = v


__all__ = ["canonical_json", "config_from_parameters", "load_config", "run_id", "to_dict"]
