"""The bid b_i = w_i - A*c_i + B*d_ij (paper section 2.3, equation 1)."""

from __future__ import annotations

import math

import pytest
from conftest import STRUCTURES

from assembly_node.bidding import compute_bid, compute_repair_bid
from tiling_assembly.structure_file import load_structure
from tiling_assembly.time_model import TimeModel

PAPER = load_structure(STRUCTURES / "paper_14.yaml")
MODEL = TimeModel(pick_time=8.0, place_time=12.0, travel_speed=0.2)


def test_bid_terms_and_value() -> None:
    remaining = [12, 14, 10]
    bid = compute_bid(PAPER, MODEL, remaining, 5, (1.0, -0.6), weight_supported=30.0, weight_distance=10.0)
    expected_w = sum(MODEL.tile_cost(PAPER, t) for t in remaining)
    assert bid.workload == pytest.approx(expected_w)
    assert bid.supported_count == 2  # 5 directly supports 10 and 12, not 14
    centre = PAPER.tiles[5].centroid
    assert bid.cache_distance == pytest.approx(math.hypot(centre[0] - 1.0, centre[1] + 0.6))
    assert bid.value == pytest.approx(expected_w - 30.0 * 2 + 10.0 * bid.cache_distance)


def test_the_tile_itself_is_not_part_of_the_workload() -> None:
    with_tile = compute_bid(PAPER, MODEL, [5, 12], 5, None, 30.0, 10.0)
    without = compute_bid(PAPER, MODEL, [12], 5, None, 30.0, 10.0)
    assert with_tile == without
    assert with_tile.cache_distance == 0.0


def test_robot_waiting_for_the_tile_with_a_near_cache_bids_lower() -> None:
    busy_far = compute_bid(PAPER, MODEL, [1, 2, 3], 4, (-3.0, 3.0), 30.0, 10.0)
    waiting_near = compute_bid(PAPER, MODEL, [11, 1, 2], 4, (-0.2, 0.0), 30.0, 10.0)
    assert waiting_near.supported_count == 1 and busy_far.supported_count == 0
    assert waiting_near.value < busy_far.value


def test_a_robot_with_nothing_left_bids_in_floats() -> None:
    # message fields are float64: an int here crashes the node when it publishes the bid
    bid = compute_bid(PAPER, MODEL, [], 5, None, 30.0, 10.0)
    assert isinstance(bid.workload, float) and isinstance(bid.value, float)
    assert bid.value == 0.0


def test_a_repair_bid_counts_the_distance_from_where_the_robot_stands() -> None:
    tile = PAPER.tiles[6].centroid
    near = compute_repair_bid(PAPER, TimeModel(), [9, 13], 6, (tile[0] + 0.5, tile[1]), 30.0, 10.0)
    far = compute_repair_bid(PAPER, TimeModel(), [9, 13], 6, (tile[0] + 3.0, tile[1]), 30.0, 10.0)
    assert math.isclose(near.cache_distance, 0.5) and math.isclose(far.cache_distance, 3.0)
    assert near.supported_count == 1  # 9 rests on 6
    assert math.isclose(far.value - near.value, 25.0)
