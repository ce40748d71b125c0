"""The configuration of one replay run as frozen dataclasses: the stack's parameters and the engine's.

Reading a TOML file and `--set key=value` overrides into these, and the run id, live in
`replay.run.config`; the engine needs only the values.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from replay.stack.config import StackConfig

# the positioning methods the engine runs on archived USBL epochs (replay.engine.usbl.positioning)
USBL_UPDATE_METHODS: tuple[str, ...] = ("kmcdf2", "gar", "ear", "lms", "lhc")


@dataclass(frozen=True)
class EngineConfig:
    """What the engine does around the stack: windows, pacing, gaps, USBL grouping."""

    window_s: tuple[float, float] | None = None   # replay only [t0, t1] s from the trial start
    rate: float = 0.0                             # 0 = as fast as possible; X = X times real time
    lag_s: float = 5.0                            # how far the engine looks ahead for leader positions
    max_gap_s: float = 3.0                        # longest gap to interpolate a position across
    node_max_gap_s: float = 30.0                  # moored USBL buoys report GPS seldom; they barely move
    usbl_group_s: float = 2.5                     # observations of one ping: within this of the first
    kmcdf: bool = True                            # USBL epochs through KMCDF
    kmcdf_rho_m: float = 30.0
    kmcdf_phase_noise_rad: float = 0.1
    # a positioning method whose USBL fixes of a follower update its filters (every method but
    # dead reckoning) as position measurements; "" = none, as in paper A's comparison
    usbl_update: str = ""
    usbl_update_sigma_m: float = 3.0              # fix sigma per axis where the method gives no covariance


@dataclass(frozen=True)
class RunConfig:
    """The whole configuration of one replay run."""

    stack: StackConfig = field(default_factory=StackConfig)
    engine: EngineConfig = field(default_factory=EngineConfig)


__all__ = ["USBL_UPDATE_METHODS", "EngineConfig", "RunConfig"]
