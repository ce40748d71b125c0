"""One colour per method, for every picture of a run: the Rerun views, the HTML report, KML tracks.

Every colour is of middle lightness so it reads on the viewer's dark theme,
the web viewer's light one and a white page alike; the truth is a middle
grey (drawn wider), never white. The seven methods most often in view
(dead_reckoning, ckf, ackf, chi_square, anfis, drift_reference, kmcdf2) take
the Okabe-Ito colours, told apart with the common colour-vision deficiencies
(deuteranopia, protanopia, tritanopia); every other pair differs by at least
25 CIELAB units for normal vision (tests/test_palette.py measures both).
"""

from __future__ import annotations

import zlib

from replay.stack.methods import METHOD_TABLE, methods

# what is drawn beside the methods: sources of a trial and the truth (the methods' colours are the method table's)
SOURCE_RGB: dict[str, tuple[int, int, int]] = {
    "gps": (128, 128, 128),
    "ins": (210, 90, 90),
    "truth": (128, 128, 128),
    "measured": (195, 180, 255),
    "dead_reckoning (DVL)": (255, 0, 0),
}


def palette() -> dict[str, tuple[int, int, int]]:
    """Name -> RGB: GPS and INS, every method of the table in its order, then the truth (the class ids' order)."""
    first = {k: SOURCE_RGB[k] for k in ("gps", "ins")}
    return {**first, **{m.name: m.colour for m in methods()}, **SOURCE_RGB}


def method_rgb(name: str) -> tuple[int, int, int]:
    """A method's colour; an unknown name gets a stable mid-tone from its hash."""
    rgb = SOURCE_RGB.get(name) or (METHOD_TABLE[name].colour if name in METHOD_TABLE else None)
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
