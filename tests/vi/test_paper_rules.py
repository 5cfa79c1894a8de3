"""The paper's classification rules (section 2.2.3), each on hand-made support counts."""

from __future__ import annotations

import numpy as np
import pytest

from vi_node.classify import TileState, classify_paper, support_ratio


def states(p: list[int], v: list[int], **kwargs: float) -> list[TileState]:
    result, _ = classify_paper(np.array(p), np.array(v), **kwargs)
    return [TileState(int(s)) for s in result]


def test_no_virtual_support_is_occluded() -> None:
    # v_i = 0 => occluded, whatever the physical support
    assert states([0, 500, 5000], [0, 0, 0]) == [TileState.OCCLUDED] * 3


def test_virtual_but_no_physical_support_is_missing() -> None:
    # v_i != 0 and p_i = 0 => missing
    assert states([0], [400]) == [TileState.MISSING]


def test_ratio_at_or_below_threshold_is_missing() -> None:
    # v_i != 0, p_i != 0, r <= t_r => missing, in both directions of the ratio
    assert states([280, 400, 1000], [400, 280, 400]) == [
        TileState.MISSING,
        TileState.MISSING,
        TileState.MISSING,
    ]
    _, ratio = classify_paper(np.array([280]), np.array([400]))
    assert ratio[0] == pytest.approx(0.7)


def test_ratio_above_threshold_is_present() -> None:
    # v_i != 0, p_i != 0, r > t_r => present, in both directions of the ratio
    assert states([281, 400, 500], [400, 281, 500]) == [TileState.PRESENT] * 3


def test_support_below_100_points_counts_as_zero() -> None:
    # 99 virtual points are no virtual support (occluded); 99 physical points are none (missing)
    assert states([500, 99, 100], [99, 400, 100]) == [
        TileState.OCCLUDED,
        TileState.MISSING,
        TileState.PRESENT,
    ]


def test_thresholds_are_parameters() -> None:
    assert states([50], [60], min_support=10) == [TileState.PRESENT]
    assert states([300], [400], ratio_threshold=0.8) == [TileState.MISSING]
    assert states([300], [400], ratio_threshold=0.7) == [TileState.PRESENT]


def test_ratio_is_zero_when_a_count_is_zero() -> None:
    assert support_ratio(np.array([0, 5, 0]), np.array([5, 0, 0])).tolist() == [0.0, 0.0, 0.0]


def test_state_values_match_the_message_constants() -> None:
    from tiling_assembly_msgs.msg import TileState as TileStateMsg

    for state in TileState:
        assert getattr(TileStateMsg, state.name) == state.value
