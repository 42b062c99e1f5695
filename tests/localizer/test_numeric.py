"""The one angle wrap and the one validation helpers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from localizer.numeric import check_choice, check_number, check_numbers, wrap_angle


def test_wrap_angle_interval_and_types():
    assert wrap_angle(math.pi) == -math.pi  # [-π, π)
    assert wrap_angle(-math.pi) == -math.pi
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    a = wrap_angle(np.array([0.0, 7.0, -7.0]))
    assert isinstance(a, np.ndarray) and np.all((a >= -math.pi) & (a < math.pi))
    np.testing.assert_allclose(np.cos(a), np.cos([0.0, 7.0, -7.0]))
    assert isinstance(wrap_angle(1.0), float)


def test_check_number_messages_name_field_value_and_expectation():
    assert check_number("X.rate", 10, low=0.0, low_open=True, unit="Hz") == 10.0
    with pytest.raises(ValueError, match=r"^X\.rate must be a finite number > 0 \(Hz\), got -1$"):
        check_number("X.rate", -1, low=0.0, low_open=True, unit="Hz")
    with pytest.raises(ValueError, match=r"got True"):
        check_number("X.rate", True)
    with pytest.raises(ValueError, match=r"got nan"):
        check_number("X.rate", float("nan"))
    with pytest.raises(ValueError, match=r">= 0 and <= 1"):
        check_number("p", 1.5, low=0.0, high=1.0)
    assert check_number("n", 3.0, low=1, integer=True) == 3
    with pytest.raises(ValueError, match="a whole number"):
        check_number("n", 2.5, integer=True)


def test_check_numbers_and_choice():
    assert check_numbers("s", (1, 2, 3), 3, low=0.0) == (1.0, 2.0, 3.0)
    with pytest.raises(ValueError, match=r"s must be 3 numbers"):
        check_numbers("s", (1, 2), 3)
    with pytest.raises(ValueError, match=r"s\[1\] must be a finite number >= 0"):
        check_numbers("s", (1, -2, 3), 3, low=0.0)
    assert check_choice("mode", "ekf", ("ekf", "truth")) == "ekf"
    with pytest.raises(ValueError, match=r"mode must be one of ekf, truth; got 'ekg' \(did you mean 'ekf'\?\)"):
        check_choice("mode", "ekg", ("ekf", "truth"))
