"""One colour per method, for every picture of a run: the Rerun views, the HTML report, KML tracks.

Every colour is of middle lightness so it reads on the viewer's dark theme,
the web viewer's light one and a white page alike; the truth is a middle
grey (drawn wider), never white.
"""

from __future__ import annotations

import zlib

METHOD_RGB: dict[str, tuple[int, int, int]] = {
    "gps": (128, 128, 128),
    "ins": (176, 150, 110),
    "dead_reckoning": (166, 118, 29),
    "ckf": (31, 119, 230),
    "ackf": (23, 180, 200),
    "chi_square": (255, 127, 14),
    "dual_threshold": (148, 103, 189),
    "anfis": (44, 170, 44),
    "anfis_aqpso": (150, 190, 20),
    "anfis_compensation": (0, 140, 110),
    "kmcdf1": (214, 39, 40),
    "kmcdf2": (227, 80, 170),
    "gar": (200, 170, 0),
    "ear": (240, 120, 110),
    "lms": (128, 128, 0),
    "lhc": (100, 140, 255),
    "truth": (128, 128, 128),
    "measured": (255, 170, 40),
    "cusum_drift": (160, 80, 50),
    "anfis_hybrid": (90, 60, 200),
}
"""Method (or source) name -> RGB; the order is the views' fixed class-id order: new names go last."""


def method_rgb(name: str) -> tuple[int, int, int]:
    """A method's colour; an unknown name gets a stable mid-tone from its hash."""
    rgb = METHOD_RGB.get(name)
    if rgb is not None:
        return rgb
    h = zlib.crc32(name.encode())
    return (60 + h % 160, 60 + (h >> 8) % 160, 60 + (h >> 16) % 160)


def method_hex(name: str) -> str:
    """'#rrggbb' of a method's colour (matplotlib, HTML)."""
    return "#{:02x}{:02x}{:02x}".format(*method_rgb(name))


def method_kml(name: str) -> str:
    """KML's opaque 'ffbbggrr' of a method's colour."""
    r, g, b = method_rgb(name)
    return f"ff{b:02x}{g:02x}{r:02x}"
