"""The palette: every pair of colours told apart, and the methods most often in view also by colour-blind eyes.

The colour science is written here plainly (sRGB -> linear -> XYZ -> CIELAB, and
Machado, Oliveira and Fernandes' 2009 full-severity simulation matrices on linear
RGB) to judge `replay.review.palette`.
"""

from __future__ import annotations

import itertools

import numpy as np

from replay.review.palette import SOURCE_RGB, method_rgb, palette

# CIELAB distance (CIE76) below which two colours of thin lines read as one
NORMAL_MIN_DE = 25.0
CVD_MIN_DE = 15.0
OKABE_ITO = {(230, 159, 0), (86, 180, 233), (0, 158, 115), (240, 228, 66), (0, 114, 178), (213, 94, 0),
             (204, 121, 167)}
IN_VIEW = ("dead_reckoning", "ckf", "ackf", "chi_square", "anfis", "drift_reference", "kmcdf2")
MACHADO = {
    "deuteranopia": [[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
                     [-0.011820, 0.042940, 0.968881]],
    "protanopia": [[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216],
                   [-0.003882, -0.048116, 1.051998]],
    "tritanopia": [[1.255528, -0.076749, -0.178779], [-0.078411, 0.930809, 0.147602],
                   [0.004733, 0.691367, 0.303900]],
}


def lab(rgb: tuple[int, int, int], simulate: str | None = None) -> np.ndarray:
    """CIELAB (D65) of an sRGB colour, optionally as seen with a colour-vision deficiency."""
    c = np.asarray(rgb, dtype=float) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    if simulate is not None:
        linear = np.clip(np.asarray(MACHADO[simulate]) @ linear, 0.0, 1.0)
    xyz = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]) @ linear
    t = xyz / np.array([0.95047, 1.0, 1.08883])
    f = np.where(t > (6 / 29) ** 3, np.cbrt(t), t / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def test_every_pair_of_colours_is_told_apart() -> None:
    colours = {name: rgb for name, rgb in palette().items() if name not in ("truth", "gps")}
    closest = min(((float(np.linalg.norm(lab(a) - lab(b))), m, n) for (m, a), (n, b)
                   in itertools.combinations(colours.items(), 2)))
    assert closest[0] >= NORMAL_MIN_DE, closest
    for name, rgb in colours.items():       # none is the truth's grey, none too dark or too light for both themes
        assert np.linalg.norm(lab(rgb) - lab(SOURCE_RGB["gps"])) >= NORMAL_MIN_DE, name
        assert 40.0 <= lab(rgb)[0] <= 92.0, name


def test_the_methods_most_in_view_are_told_apart_by_colour_blind_eyes() -> None:
    assert {method_rgb(m) for m in IN_VIEW} == OKABE_ITO
    for kind in MACHADO:
        closest = min((float(np.linalg.norm(lab(method_rgb(m), kind) - lab(method_rgb(n), kind))), m, n)
                      for m, n in itertools.combinations(IN_VIEW, 2))
        assert closest[0] >= CVD_MIN_DE, (kind, closest)


def test_the_judge_knows_its_colours() -> None:
    # white and black are 100 apart in L*, and a deuteranope sees red and green alike
    assert np.allclose(lab((255, 255, 255)), [100, 0, 0], atol=0.1) and np.allclose(lab((0, 0, 0)), 0, atol=1e-9)
    normal = np.linalg.norm(lab((200, 60, 60)) - lab((60, 160, 60)))
    deuteranope = np.linalg.norm(lab((200, 60, 60), "deuteranopia") - lab((60, 160, 60), "deuteranopia"))
    assert deuteranope < normal / 2
