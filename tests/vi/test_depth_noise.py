"""The Kinect v1's depth noise model, which the evidence and the misplacement refits share."""

from __future__ import annotations

import numpy as np
import pytest

from vi_node.depth_noise import axial_sigma, disparity_step, resolved_motion


def test_the_noise_grows_with_the_square_of_the_depth() -> None:
    assert axial_sigma(1.0) == pytest.approx(0.001884)
    assert axial_sigma(3.0) == pytest.approx(0.014044)
    assert disparity_step(3.0) == pytest.approx(0.02565)
    depths = np.array([1.0, 2.0, 3.0])
    assert np.allclose(resolved_motion(depths), axial_sigma(depths) + 0.5 * disparity_step(depths))
    # a 2 cm motion stands out of the noise up to about 2.6 m, not at 3 m
    assert resolved_motion(2.5) < 0.02 < resolved_motion(2.7) < resolved_motion(3.0) == pytest.approx(0.0269, abs=1e-4)
