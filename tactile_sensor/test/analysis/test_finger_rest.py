"""When the fingers came to rest: the one definition every stop measurement uses."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from tactile_sensor.analysis.finger_rest import REST_TOLERANCE_M, rest_onset


def _stop(moving: int, resting: int, dt: float = 0.01) -> list[tuple[float, float]]:
    """Fingers closing 1 mm a sample for ``moving`` samples, then still."""
    path = [(i * dt, 0.06 - 1e-3 * i) for i in range(moving)]
    end = path[-1][1] if path else 0.06
    return path + [((moving + i) * dt, end) for i in range(resting)]


@given(moving=st.integers(1, 50), resting=st.integers(1, 50))
def test_the_onset_is_the_first_sample_at_the_final_opening(moving: int, resting: int) -> None:
    opening = _stop(moving, resting)
    assert rest_onset(opening, since=0.0) == opening[moving - 1][0]


def test_a_dither_within_the_tolerance_is_rest_and_one_beyond_it_is_motion() -> None:
    still = [(0.0, 0.02), (0.1, 0.02 + 0.9 * REST_TOLERANCE_M), (0.2, 0.02)]
    assert rest_onset(still, since=0.0) == 0.0
    moved = [(0.0, 0.02), (0.1, 0.02 + 1.1 * REST_TOLERANCE_M), (0.2, 0.02)]
    assert rest_onset(moved, since=0.0) == 0.2


def test_a_finger_that_passes_its_end_and_comes_back_is_still_moving() -> None:
    opening = [(0.0, 0.030), (0.1, 0.020), (0.2, 0.025), (0.3, 0.020), (0.4, 0.020)]
    assert rest_onset(opening, since=0.0) == 0.3


def test_only_the_window_counts_and_a_short_rest_is_not_yet_rest() -> None:
    opening = _stop(10, 40)  # at rest from 0.09 s to 0.49 s
    assert rest_onset(opening, since=0.2) == 0.2
    assert rest_onset(opening, since=0.0, until=0.05) == 0.05
    assert rest_onset(opening, since=0.0, hold_s=0.3) == 0.09
    assert rest_onset(opening, since=0.0, until=0.3, hold_s=0.3) is None


def test_no_sample_in_the_window_gives_none() -> None:
    assert rest_onset([], since=0.0) is None
    assert rest_onset(_stop(5, 5), since=1.0) is None
