"""KMCDF's preliminary fixes beyond the zoomed view are drawn on its rim, in their direction; the others stay."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from replay.views.positioning import on_rim

COORD = st.floats(-5000, 5000, allow_nan=False)


@given(arrays(float, st.tuples(st.integers(0, 30), st.just(2)), elements=COORD), st.floats(1.0, 100.0))
def test_fixes_beyond_the_view_land_on_its_rim_in_their_direction(offset: np.ndarray, limit: float) -> None:
    out, beyond = on_rim(offset, limit)
    reach = np.max(np.abs(offset), axis=1)
    assert np.array_equal(beyond, reach > limit)
    np.testing.assert_array_equal(out[~beyond], offset[~beyond])            # inside: untouched
    if beyond.any():
        np.testing.assert_allclose(np.max(np.abs(out[beyond]), axis=1), limit, rtol=1e-12)
        # the same direction: parallel and pointing the same way
        cross = out[beyond, 0] * offset[beyond, 1] - out[beyond, 1] * offset[beyond, 0]
        np.testing.assert_allclose(cross, 0.0, atol=1e-6 * np.max(np.abs(offset[beyond])) * limit)
        assert (np.sum(out[beyond] * offset[beyond], axis=1) > 0).all()


def test_a_rejected_fix_far_out_is_drawn_at_the_edge() -> None:
    out, beyond = on_rim(np.array([[3.0, -4.0], [740.0, 0.0], [-300.0, 400.0], [np.nan, 1.0]]), 9.5)
    assert beyond.tolist() == [False, True, True, False]
    np.testing.assert_allclose(out[:3], [[3.0, -4.0], [9.5, 0.0], [-7.125, 9.5]])
