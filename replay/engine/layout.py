"""Who is in a trial archive and what each vehicle can run: followers, leaders, buoys, topics.

Roles come from the archive's `trial` metadata; when it is missing, they are
guessed from the topics (a vehicle with USBL observations is a buoy, one with
a DVL a follower, or one with modem ranges where no vehicle has a DVL, the
rest leaders) and the guess is reported.

Each follower runs the configured methods whose inputs it holds (the method
table's ``needs``: DVL, modem ranges from a leader with a position, GPS on
the vehicle, USBL fixes); `TrialLayout.skipped` names every method no
vehicle could run, with the input it lacked.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from replay.stack.methods import INPUTS, method


@dataclass(frozen=True)
class FollowerPlan:
    """What the engine can do for one follower, and why not the rest."""

    name: str
    runnable: bool
    leaders: tuple[str, ...]
    heading_topic: str | None
    notes: tuple[str, ...] = ()
    methods: tuple[str, ...] = ()            # the configured methods whose inputs this follower holds


@dataclass
class TrialLayout:
    """Vehicles by role, the topics each has, and the per-follower plans."""

    roles: dict[str, str]
    topics: dict[str, int]                         # topic -> message count
    followers: list[FollowerPlan] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)   # method -> what no vehicle held ("needs ...")
    # the other position topics (an INS of its own, a local x/y on an origin, node reports): topic -> (vehicle, source)
    sources: dict[str, tuple[str, str]] = field(default_factory=dict)

    def has(self, vehicle: str, sensor: str) -> bool:
        """True when /<vehicle>/<sensor> holds messages."""
        return self.topics.get(f"/{vehicle}/{sensor}", 0) > 0

    def by_role(self, role: str) -> list[str]:
        """Vehicle names with a role, in archive order."""
        return [v for v, r in self.roles.items() if r == role]

    def positioned_leaders(self) -> list[str]:
        """The leaders with a position a range can be taken against (an INS or GPS)."""
        return [ld for ld in self.by_role("leader") if self.has(ld, "ins") or self.has(ld, "gps")]

    def inputs(self, vehicle: str) -> frozenset[str]:
        """The method-table inputs a vehicle holds (USBL fixes are the trial's: a buoy's observations)."""
        held = {"dvl": self.has(vehicle, "dvl"), "gps": self.has(vehicle, "gps"),
                "ranges": self.has(vehicle, "modem/range") and bool(self.positioned_leaders()),
                "usbl": any(self.has(b, "usbl") for b in self.by_role("buoy"))}
        return frozenset(k for k, v in held.items() if v)

    def positions(self) -> list[str]:
        """The vehicles with a position of any kind (GPS fixes, an INS or autopilot solution, another source)."""
        held = [v for v in self.roles if self.has(v, "gps") or self.has(v, "ins")]
        return held + sorted({v for v, _ in self.sources.values()} - set(held))


def _guess_roles(topics: dict[str, int]) -> dict[str, str]:
    vehicles: dict[str, set[str]] = {}
    for topic in topics:
        parts = topic.strip("/").split("/")
        if len(parts) >= 2 and parts[0] not in ("replay", "diagnostics"):
            vehicles.setdefault(parts[0], set()).add("/".join(parts[1:]))
    # leaders' modems log ranges too: the DVL marks a follower, ranges only where no vehicle has one
    mark = "dvl" if any("dvl" in s for s in vehicles.values()) else "modem/range"
    roles = {}
    for name, sensors in vehicles.items():
        if "usbl" in sensors:
            roles[name] = "buoy"
        elif mark in sensors:
            roles[name] = "follower"
        else:
            roles[name] = "leader"
    return roles


def plan_trial(trial_meta: dict | None, topics: dict[str, int], methods: Sequence[str] = (),
               positions: Sequence[str] = ()) -> TrialLayout:
    """Work out roles and per-follower plans, with one note per thing that cannot run.

    `methods` (the configuration's) are given to each follower that holds
    their inputs; those no follower holds go to `TrialLayout.skipped`.
    `positions` are the archive's position topics (LocationFix or InsState);
    those beyond /<v>/gps and /<v>/ins become `TrialLayout.sources`.
    """
    vehicles = (trial_meta or {}).get("vehicles") or []
    if vehicles:
        roles = {v["name"]: v.get("role") or "" for v in vehicles if isinstance(v, dict) and "name" in v}
        if "" in roles.values():      # a role left out of the manifest: guessed from the vehicle's sensors
            guessed = _guess_roles(topics)
            roles = {name: role or guessed.get(name, "leader") for name, role in roles.items()}
        layout = TrialLayout(roles, dict(topics))
    else:
        layout = TrialLayout(_guess_roles(topics), dict(topics))
        layout.notes.append("no trial metadata: roles guessed from topics "
                            + ", ".join(f"{v}={r}" for v, r in layout.roles.items()))
    leaders = layout.by_role("leader")
    for f in layout.by_role("follower"):
        layout.followers.append(_plan_follower(layout, f, methods))
    layout.skipped = _skipped(layout, methods)
    for topic in positions:
        parts = topic.strip("/").split("/", 1)
        if len(parts) == 2 and parts[1] not in ("gps", "ins") and topics.get(topic, 0) > 0:
            layout.sources[topic] = (parts[0], parts[1])
    for leader in leaders:
        if not (layout.has(leader, "ins") or layout.has(leader, "gps")):
            layout.notes.append(f"leader {leader}: no INS and no GPS: its ranges cannot be used")
    return layout


def _skipped(layout: TrialLayout, methods: Sequence[str]) -> dict[str, str]:
    """Each method no runnable follower runs, with what it lacked on the vehicle closest to running it.

    The stack runs on followers: the candidates are the followers, else (a trial without one) every vehicle
    but the buoys.
    """
    running = {m for p in layout.followers if p.runnable for m in p.methods}
    followers = [p.name for p in layout.followers]
    vehicles = followers or [v for v, r in layout.roles.items() if r != "buoy"] or list(layout.roles)
    held = {v: layout.inputs(v) for v in vehicles}
    out = {}
    for name in methods:
        if name in running:
            continue
        entry = method(name)
        closest = min(vehicles, key=lambda v: len(entry.missing(held[v])), default=None)
        lacking = entry.missing(held[closest]) if closest is not None else list(entry.needs)
        if lacking:
            out[name] = "needs " + " and ".join(INPUTS.get(n, n) for n in lacking)
        elif closest in followers:      # its inputs are there, on a follower with no position to start from
            out[name] = "needs a position to start from (no GPS fix and no INS position on the follower)"
        elif closest is not None:
            out[name] = f"runs on a follower: {closest}, which holds its inputs, is a {layout.roles[closest]}"
    return out


def _plan_follower(layout: TrialLayout, name: str, methods: Sequence[str]) -> FollowerPlan:
    notes: list[str] = []
    usable = tuple(layout.positioned_leaders())
    runnable = True
    if not layout.has(name, "dvl"):
        notes.append(f"follower {name}: no /{name}/dvl: nothing can run for this follower")
        runnable = False
    heading = f"/{name}/ins" if layout.has(name, "ins") else None
    if heading is None and runnable:
        notes.append(f"follower {name}: no /{name}/ins heading: body-frame DVL cannot be dead-reckoned; "
                     "only earth-frame DVL velocities will be used")
    if not layout.has(name, "gps") and not layout.has(name, "ins"):
        notes.append(f"follower {name}: no GPS and no INS position: no initial fix, nothing can run")
        runnable = False
    elif not layout.has(name, "gps"):
        notes.append(f"follower {name}: no /{name}/gps: no labels and no errors; detectors cannot be trained")
    if not layout.has(name, "modem/range"):
        notes.append(f"follower {name}: no /{name}/modem/range: dead reckoning only")
    held = layout.inputs(name)
    runs = tuple(m for m in methods if not method(m).missing(held)) if runnable else ()
    return FollowerPlan(name, runnable, usable, heading, tuple(notes), runs)
