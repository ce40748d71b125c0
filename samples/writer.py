"""Writing a simulated trial to disk: vendor logs, manifest, truth, labels and the scenario.

Each log is written with the vendor encoders of `formats/` (the same code the
decoders are tested against), as the instrument or its data logger would
write it. Output is byte-identical for the same scenario and seed: fixed
float formatting, vehicles in manifest order, no wall-clock time anywhere.

Directory layout::

    README.md             what is here
    trial.toml            the manifest (docs/design.md section 4)
    scenario.toml         the scenario used, `auvreplay simulate --scenario` reads it back
    truth.csv             every vehicle's true track at `truth_csv_rate_hz`
    ranges.csv            every ranging epoch: true and measured range, GPS range, label
    usbl.csv              every USBL node epoch: true and measured delay/phases, abnormal flags
    anomalies.csv         injected anomaly intervals (scenario and natural), labelled by kind
    <vehicle>/<sensor>.log
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import fields, is_dataclass
from pathlib import Path

import numpy as np

from . import logs_acoustic, logs_nav
from .anomalies import KIND_CODES
from .scenario import scenario_to_toml
from .simulator import SimulatedTrial

TRUTH_CSV_RATE_HZ = 1.0

# (sensor, format, file name, writer, manifest options); writer(trial, vehicle name) -> bytes
LogPlan = tuple[str, str, str, Callable[[SimulatedTrial, str], bytes], dict]


def _plans(trial: SimulatedTrial, name: str, role: str) -> list[LogPlan]:
    """Which logs each vehicle carries and in which vendor format."""
    c = trial.scenario.ranging.sound_speed_mps
    modem_opts = {"sound_speed_mps": c}
    if role == "buoy":
        return [
            ("gps", "nmea", "gps.log", logs_nav.nmea_gps, {}),
            ("usbl", "evologics", "usbl.log", logs_acoustic.evologics_usbl,
             {"sound_speed_mps": c, "carrier_hz": trial.scenario.usbl.frequency_hz}),
        ]
    if name == "leader2":
        gps: LogPlan = ("gps", "novatel", "gps.log", logs_nav.novatel_gps, {})
    else:
        gps = ("gps", "nmea", "gps.log", logs_nav.nmea_gps, {})
    if role == "leader":
        ins: LogPlan = ("ins", "phins", "ins.log", logs_nav.phins_ins, {})
    else:
        ins = ("ins", "novatel", "ins.log", logs_nav.novatel_ins, {})
    return [gps, ins, ("dvl", "pd0", "dvl.pd0", logs_nav.pd0_dvl, {}),
            ("modem", "micromodem", "modem.log", logs_acoustic.micromodem_log, modem_opts)]


def _fmt_value(v: object) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, float):
        return repr(v)
    return str(v)


def manifest_text(trial: SimulatedTrial) -> str:
    """The trial manifest (TOML) for the logs `write_trial` writes."""
    t = trial.scenario.trial
    out = [
        "# Simulated lake trial written by `auvreplay simulate` (samples/).",
        f"# seed = {trial.seed}; truth in truth.csv, ranges.csv, usbl.csv; labels in anomalies.csv",
        "[trial]", f'name = "{t.name}"', f'date = "{t.date}"',
        f"sound_speed_mps = {trial.scenario.ranging.sound_speed_mps!r}", "",
    ]
    for name, role, address in _roster(trial):
        out += ["[[vehicles]]", f'name = "{name}"', f'role = "{role}"', f"modem_address = {address}"]
        if role == "buoy":
            b = next(b for b in trial.buoys if b.name == name)
            out += [f"latitude = {b.lat_deg:.8f}", f"longitude = {b.lon_deg:.8f}", f"depth_m = {b.depth_m!r}"]
        out.append("")
        for sensor, fmt, fname, _, opts in _plans(trial, name, role):
            out += ["[[vehicles.logs]]", f'sensor = "{sensor}"', f'format = "{fmt}"',
                    f'path = "{name}/{fname}"', "clock_offset_s = 0.0"]
            out += [f"{k} = {_fmt_value(v)}" for k, v in opts.items()]
            out.append("")
    return "\n".join(out)


def _roster(trial: SimulatedTrial) -> list[tuple[str, str, int]]:
    return [(v.name, v.role, v.modem_address) for v in trial.vehicles] + [
        (b.name, "buoy", b.modem_address) for b in trial.buoys]


def truth_csv(trial: SimulatedTrial) -> str:
    """True tracks of every vehicle at TRUTH_CSV_RATE_HZ, fixed decimals (1 cm, 1 mm/s)."""
    rows = ["vehicle,t_s,latitude_deg,longitude_deg,depth_m,heading_deg,velocity_north_mps,velocity_east_mps"]
    step = max(int(round(trial.scenario.trial.truth_rate_hz / TRUTH_CSV_RATE_HZ)), 1)
    for v in trial.vehicles:
        tr = v.track
        idx = np.arange(0, len(tr.t_s), step)
        cols = np.column_stack([tr.t_s, tr.lat_deg, tr.lon_deg, tr.depth_m, tr.heading_deg,
                                tr.vel_north_mps, tr.vel_east_mps])[idx]
        fmt = "{},{:.1f},{:.7f},{:.7f},{:.2f},{:.2f},{:.3f},{:.3f}"
        rows += [fmt.format(v.name, *row) for row in cols]
    return "\n".join(rows) + "\n"


def ranges_csv(trial: SimulatedTrial) -> str:
    """Every ranging epoch: measured vs true slant range, the GPS range and the label."""
    r = trial.ranges
    kinds = {code: kind for kind, code in KIND_CODES.items()}
    rows = ["t_s,follower,leader,range_true_m,range_m,travel_time_s,z_m,z_gps_m,label,injected"]
    for i in range(len(r.t_s)):
        rows.append(f"{r.t_s[i]:.1f},{r.follower[i]},{r.leader[i]},{r.range_true_m[i]:.3f},{r.range_m[i]:.3f},"
                    f"{r.travel_time_s[i]:.6f},{r.z_m[i]:.3f},{r.z_gps_m[i]:.3f},{r.label[i]},"
                    f"{kinds[int(r.injected[i])]}")
    return "\n".join(rows) + "\n"


def usbl_csv(trial: SimulatedTrial) -> str:
    """Every node's observation of every beacon: true and measured delay and phases, flags."""
    u = trial.usbl
    rows = ["t_s,node,target,delay_true_s,delay_s,phase_x_true_rad,phase_x_rad,phase_y_true_rad,phase_y_rad,"
            "abnormal_delay,abnormal_phase"]
    for i in range(len(u.t_s)):
        for j, node in enumerate(u.nodes):
            rows.append(f"{u.t_s[i]:.1f},{node},{u.target},{u.delay_true_s[i, j]:.7f},{u.delay_s[i, j]:.7f},"
                        f"{u.phase_x_true_rad[i, j]:.4f},{u.phase_x_rad[i, j]:.4f},{u.phase_y_true_rad[i, j]:.4f},"
                        f"{u.phase_y_rad[i, j]:.4f},{int(u.abnormal_delay[i, j])},{int(u.abnormal_phase[i, j])}")
    return "\n".join(rows) + "\n"


def anomalies_csv(trial: SimulatedTrial) -> str:
    """Injected anomaly intervals: who measured, which link, kind, [start, end] s and UTC."""
    rows = ["vehicle,leader,kind,start_s,end_s,start_utc,end_utc,origin,magnitude_m"]
    for iv in trial.intervals:
        a, b = (logs_acoustic.iso(int(trial.t_ns(x))) for x in (iv.start_s, iv.end_s))
        rows.append(f"{iv.vehicle},{iv.leader},{iv.kind},{iv.start_s:.1f},{iv.end_s:.1f},{a},{b},{iv.origin},"
                    f"{iv.magnitude_m:.2f}")
    return "\n".join(rows) + "\n"


def readme(trial: SimulatedTrial) -> str:
    """A short description of the trial directory."""
    t = trial.scenario.trial
    r = trial.ranges
    test = r.t_s > t.training_window_s
    lines = [
        f"# {t.name}: a simulated lake trial (seed {trial.seed})",
        "",
        "Written by `auvreplay simulate` (package `samples`); `auvreplay record trial.toml -o trial.mcap`",
        "archives it. Nothing here was measured: the scenario (`scenario.toml`) follows the source lake",
        "trial described in docs/design.md section 15.",
        "",
        f"- {t.date} from {t.start_time_utc} UTC, {t.duration_s:g} s, around {t.origin_lat_deg:g} N "
        f"{t.origin_lon_deg:g} E",
        "- vehicles: " + ", ".join(f"{v.name} ({v.role}, modem {v.modem_address})" for v in trial.vehicles),
        "- USBL buoys: " + ", ".join(f"{b.name} (address {b.modem_address})" for b in trial.buoys),
        f"- {len(r.t_s)} ranges, {int(test.sum())} after the {t.training_window_s:g} s training window, "
        f"{int(r.label[test].sum())} of them labelled anomalous (|Z_gps - Z| > 9 m)",
        "",
        "Files: `trial.toml` (manifest), `scenario.toml`, `<vehicle>/*.log|.pd0` (vendor logs),",
        "`truth.csv` (true tracks, 1 Hz), `ranges.csv` (every ranging epoch: true and measured range,",
        "GPS range, label, injected kind), `usbl.csv` (every node observation: true and measured delay",
        "and phases, abnormal flags), `anomalies.csv` (injected intervals; times in seconds from the",
        "start and UTC). Seconds in the CSVs count from the trial start.",
    ]
    if trial.notes:
        lines += ["", f"Motion: the GPS tracks of `{trial.scenario.tracks.archive}` (`simulate --tracks`); only the",
                  "acoustics and the DR sensors are simulated along them.", "", *(f"- {n}" for n in trial.notes)]
    return "\n".join(lines) + "\n"


WRITER_INPUTS: dict[Callable[[SimulatedTrial, str], bytes], tuple[str, ...]] = {
    logs_nav.nmea_gps: (), logs_nav.novatel_gps: (), logs_nav.phins_ins: (), logs_nav.novatel_ins: (),
    logs_nav.pd0_dvl: (), logs_acoustic.micromodem_log: ("ranges", "pings"), logs_acoustic.evologics_usbl: ("usbl",)}
"""What each writer's log is a function of, besides the start time, the scenario's sensor tables (`_SENSOR_TABLES`)
and the vehicles' and buoys' simulated series: the trial's other series it reads (never the scenario's anomalies).
A writer not listed is never shared (`log_files`' `like`)."""
_SENSOR_TABLES = ("gps", "ins", "dvl", "ranging", "usbl")
_SERIES = ("vehicles", "buoys", "ranges", "pings", "usbl")


def _same_values(a: object, b: object) -> bool:
    """Deep equality of simulated series: dataclasses field by field, arrays element by element (NaN = NaN)."""
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype == b.dtype and bool(
            np.array_equal(a, b, equal_nan=a.dtype.kind in "fc"))
    if is_dataclass(a) and not isinstance(a, type):
        return type(a) is type(b) and all(_same_values(getattr(a, f.name), getattr(b, f.name)) for f in fields(a))
    if isinstance(a, (tuple, list)):
        return isinstance(b, type(a)) and len(a) == len(b) and all(_same_values(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and bool(a == b)


def same_inputs(a: SimulatedTrial, b: SimulatedTrial) -> set[str]:
    """The simulated series (`_SERIES`) two trials hold equal, when their start and sensor tables are (else none)."""
    tables = [getattr(a.scenario, t) == getattr(b.scenario, t) for t in _SENSOR_TABLES]
    if a.start_ns != b.start_ns or not all(tables):
        return set()
    return {f for f in _SERIES if _same_values(getattr(a, f), getattr(b, f))}


def log_files(trial: SimulatedTrial,
              like: tuple[SimulatedTrial, dict[str, bytes]] | None = None) -> dict[str, bytes]:
    """What `record` reads of the trial: the manifest and every vendor log (relative POSIX path -> bytes).

    `like`: another trial and its `log_files`; a log whose writer's inputs (`WRITER_INPUTS`) are equal in
    both is taken from it as it is (a drift rate of `evaluate`'s sweep changes only the ranges).
    """
    files = {"trial.toml": manifest_text(trial).encode()}
    same = same_inputs(trial, like[0]) if like is not None else set()
    for name, role, _ in _roster(trial):
        for _, _, fname, write, _ in _plans(trial, name, role):
            rel = f"{name}/{fname}"
            inputs = WRITER_INPUTS.get(write)
            if like is not None and inputs is not None and {"vehicles", "buoys", *inputs} <= same \
                    and rel in like[1]:
                files[rel] = like[1][rel]
            else:
                files[rel] = write(trial, name)
    return files


def render(trial: SimulatedTrial) -> dict[str, bytes]:
    """Every file of the trial directory: relative POSIX path -> bytes."""
    files: dict[str, bytes] = {
        "README.md": readme(trial).encode(),
        "scenario.toml": scenario_to_toml(trial.scenario).encode(),
        "truth.csv": truth_csv(trial).encode(),
        "ranges.csv": ranges_csv(trial).encode(),
        "usbl.csv": usbl_csv(trial).encode(),
        "anomalies.csv": anomalies_csv(trial).encode(),
    }
    return {**files, **log_files(trial)}


def write_trial(trial: SimulatedTrial, out_dir: str | Path, logs_only: bool = False) -> list[Path]:
    """Write the trial directory (`logs_only`: the manifest and the logs, what `record` reads); the paths (sorted)."""
    return write_files(log_files(trial) if logs_only else render(trial), out_dir)


def write_files(files: dict[str, bytes], out_dir: str | Path) -> list[Path]:
    """Write `render`'s or `log_files`' files under `out_dir`; the paths (sorted)."""
    root = Path(out_dir)
    written = []
    for rel, data in sorted(files.items()):
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        written.append(path)
    return written
