"""One colour per method, for every picture of a run (the HTML report, KML tracks; the Rerun views' table
in replay/views/common.py holds the same RGB values and should come to import them from here).

Truth is drawn in a neutral that reads on dark and light backgrounds alike.
"""

from __future__ import annotations

import zlib

METHOD_RGB: dict[str, tuple[int, int, int]] = {
    "gps": (90, 90, 90),
    "ins": (150, 150, 150),
    "dead_reckoning": (166, 118, 29),
    "ckf": (31, 119, 230),
    "ackf": (23, 190, 207),
    "chi_square": (255, 127, 14),
    "dual_threshold": (148, 103, 189),
    "anfis": (44, 200, 44),
    "anfis_aqpso": (188, 230, 34),
    "anfis_compensation": (0, 150, 120),
    "kmcdf1": (214, 39, 40),
    "kmcdf2": (227, 119, 194),
    "gar": (240, 220, 60),
    "ear": (255, 152, 150),
    "lms": (128, 128, 0),
    "lhc": (120, 170, 255),
}


def method_rgb(name: str) -> tuple[int, int, int]:
    """A method's colour; an unknown name gets a stable mid-tone from its hash."""
    rgb = METHOD_RGB.get(name)
    if rgb is not None:
        return rgb
    h = zlib.crc32(name.encode())
    return (80 + h % 160, 80 + (h >> 8) % 160, 80 + (h >> 16) % 160)


def method_hex(name: str) -> str:
    """'#rrggbb' of a method's colour (matplotlib, HTML)."""
    return "#{:02x}{:02x}{:02x}".format(*method_rgb(name))


def method_kml(name: str) -> str:
    """KML's opaque 'ffbbggrr' of a method's colour."""
    r, g, b = method_rgb(name)
    return f"ff{b:02x}{g:02x}{r:02x}"
