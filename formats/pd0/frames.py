"""RDI coordinate frames: Janus beam velocities to instrument axes, bottom track to vehicle velocity.

Every function here takes four per-beam (or per-axis) values that are either
floats (one ensemble, `formats.pd0.ensembles`) or equal-length numpy columns
(a run of ensembles, `formats.pd0.blocks` through `recorders.dvl`): the same
IEEE operations in the same order either way, so the two paths give the same
bits. PD4/PD5 (`formats.pd4`) use `beam_to_instrument` too.
"""

from __future__ import annotations

import math
from typing import Sequence, TypeVar

import numpy as np

V = TypeVar("V", float, np.ndarray)  # one ensemble's value, or one column of a run of ensembles


def beam_to_instrument(beams: Sequence[V], beam_angle_deg: float, convex: bool = True) -> tuple[V, V, V, V]:
    """Janus beam velocities to instrument X, Y, Z, error (RDI "ADCP Coordinate Transformation").

    X = c a (b1 - b2), Y = c a (b4 - b3), Z = b (b1 + b2 + b3 + b4),
    E = d (b1 + b2 - b3 - b4), with a = 1/(2 sin θ), b = 1/(4 cos θ), d = a/√2,
    c = +1 convex, -1 concave. NaN in, NaN out.
    """
    th = math.radians(beam_angle_deg)
    a, b = 1 / (2 * math.sin(th)), 1 / (4 * math.cos(th))
    c = 1.0 if convex else -1.0
    b1, b2, b3, b4 = beams
    return (c * a * (b1 - b2), c * a * (b4 - b3), b * (b1 + b2 + b3 + b4),
            a / math.sqrt(2) * (b1 + b2 - b3 - b4))


def vehicle_velocity(coordinates: str, bottom: Sequence[V], beam_angle_deg: float = 30.0,
                     convex: bool = True) -> tuple[str, V, V, V, V]:
    """Vehicle velocity over ground from PD0 bottom-track values: (frame, x, y, z, error).

    PD0 reports the bottom moving past a stationary instrument, so the vehicle
    velocity is the negation. Frames: ship (RDI x starboard, y forward, z up)
    becomes BODY_FRD (x forward, y starboard, z down): (-bt_y, -bt_x, +bt_z);
    earth (east, north, up) becomes EARTH_NED the same way; instrument stays in
    the transducer's axes, negated; beam velocities are first transformed to
    instrument axes (`beam_to_instrument`). The error velocity is passed on
    as reported (its sign carries no direction).
    """
    b = tuple(bottom)
    if coordinates == "beam":
        b = beam_to_instrument(b, beam_angle_deg, convex)
        coordinates = "instrument"
    if coordinates == "instrument":
        return ("INSTRUMENT", -b[0], -b[1], -b[2], b[3])
    frame = "BODY_FRD" if coordinates == "ship" else "EARTH_NED"
    return (frame, -b[1], -b[0], b[2], b[3])


def bottom_velocity_from_frd(forward: float, starboard: float, down: float,
                             error: float = 0.0) -> tuple[float, float, float, float]:
    """PD0 ship-coordinate bottom-track values for a vehicle moving (forward, starboard, down) m/s.

    The inverse of `vehicle_velocity("ship", ...)`; the simulator uses it.
    Also valid for earth coordinates with (north, east, down).
    """
    return (-starboard, -forward, down, error)
