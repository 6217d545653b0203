"""Value tests of drivetrain_ctrl.linear.clutch (issue 22 item 4): the speed-source shuffle
threshold against the eigenvalues of the three-state driveline written out here, and its
first-order form (``./dev mutate drivetrain_ctrl/linear/clutch.py``)."""

from __future__ import annotations

import numpy as np
import pytest

from drivetrain_ctrl.linear.clutch import shuffle_speed_source_threshold


def _eig(J: float, m: float, h: float, b: float, e: float, d: float) -> np.ndarray:
    # states (omega_J, omega_m, twist): J w_J' = -d w_J - h q - b (w_J - w_m),
    # m w_m' = -e w_m + h q + b (w_J - w_m), q' = w_J - w_m
    A = np.array(
        [
            [-(d + b) / J, b / J, -h / J],
            [b / m, -(e + b) / m, h / m],
            [1.0, -1.0, 0.0],
        ]
    )
    return np.linalg.eigvals(A)


@pytest.mark.parametrize(
    ("J", "m", "h", "b", "e"),
    [(0.1, 10.0, 500.0, 1.0, 0.5), (0.05, 3.0, 2000.0, 0.2, 0.0), (0.2, 8.0, 300.0, 0.0, 2.0)],
)
def test_the_threshold_puts_the_shuffle_pair_on_the_imaginary_axis(
    J: float, m: float, h: float, b: float, e: float
) -> None:
    d, w = shuffle_speed_source_threshold(J=J, m=m, h=h, b=b, e=e)
    lam = _eig(J, m, h, b, e, d)
    pair = lam[np.argmax(np.abs(lam.imag))]
    assert abs(pair.real) < 1e-9 * abs(pair)
    assert abs(pair.imag) == pytest.approx(w, rel=1e-9)
    # the pair crosses there: a little less (more negative) damping, Re > 0; a little more, < 0
    for dd, sign in ((d - 1e-3 * abs(d), 1.0), (d + 1e-3 * abs(d), -1.0)):
        lam = _eig(J, m, h, b, e, dd)
        assert sign * lam[np.argmax(np.abs(lam.imag))].real > 0


def test_the_first_order_form_for_light_damping() -> None:
    J, m, h, b, e = 0.1, 10.0, 500.0, 1e-3, 2e-3
    d, w = shuffle_speed_source_threshold(J=J, m=m, h=h, b=b, e=e)
    approx = -b * (1 + J / m) ** 2 - e * (J / m) ** 2
    assert d == pytest.approx(approx, rel=1e-3)
    assert w == pytest.approx(np.sqrt(h * (J + m) / (J * m)), rel=1e-4)
