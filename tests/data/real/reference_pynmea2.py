"""Prints pynmea2 1.19.0's reading of the real NMEA fixtures (any venv with pynmea2==1.19.0).

The numbers in tests/test_real_vendor_files.py were copied from this output.
"""

from pathlib import Path

import pynmea2

HERE = Path(__file__).parent
FIELDS = ("timestamp", "datestamp", "latitude", "longitude", "gps_qual", "num_sats",
          "horizontal_dil", "altitude", "geo_sep", "true_track", "mag_track",
          "spd_over_grnd_kts", "spd_over_grnd_kmph", "spd_over_grnd", "true_course",
          "mag_variation", "mag_var_dir", "status", "faa_mode", "mode_indicator", "rms",
          "std_dev_major", "std_dev_minor", "orientation", "std_dev_latitude",
          "std_dev_longitude", "std_dev_altitude", "day", "month", "year", "local_zone",
          "local_zone_minutes", "heading", "true_heading", "is_true_heading", "roll", "pitch", "heave", "roll_accuracy",
          "pitch_accuracy", "heading_accuracy", "aiding_status", "imu_status", "beam",
          "dt1", "dt2", "bv", "fom", "dist", "stat", "vx", "vy", "vz", "d1", "d2", "d3", "d4",
          "battery_voltage", "sound_speed", "pressure", "temp", "dir")


def show(line: str) -> None:
    """One line: pynmea2's fields, or the exception it raises."""
    print(line)
    try:
        msg = pynmea2.parse(line, check=True)
    except Exception as exc:  # noqa: BLE001 - the reference's verdict is the output
        print("   ", type(exc).__name__, exc)
        return
    print("   ", type(msg).__name__)
    for name in FIELDS:
        try:
            value = getattr(msg, name)
        except AttributeError:  # not a field of this sentence type
            continue
        except ValueError as exc:
            value = f"<ValueError: {exc}>"
        if value not in (None, ""):
            print("   ", name, repr(value))


def main() -> None:
    for path in sorted(HERE.glob("*.log")) + sorted(HERE.glob("*.nmea")):
        print("==", path.name)
        for line in path.read_text(errors="replace").splitlines():
            show(line)


if __name__ == "__main__":
    main()
