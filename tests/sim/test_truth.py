"""The ground-truth rules of docs/affordances.md, one test per rule. Expected values are worked out from the
document by hand (markings m_j = (N/2 - j) w), not from the code."""
import math

import numpy as np
import pytest

from core.worlds.highway import HIGHWAY, INACTIVE, INDICATORS, LABEL_SETS, PAPER_INDICATORS, indicators_to_dict
from sim.highway.truth import affordances, ground_truth, rear_indicators, truth_record
from sim.track import load_track

# oval: straight 500 m from s = 0, then a 150 m radius half circle (s 500..971.2), straight, half circle
S_STRAIGHT = 100.0


@pytest.fixture(scope="module")
def tracks():
    return {n: load_track("oval", lanes=n) for n in (1, 2, 3, 4)}


def ind(track, d, s=S_STRAIGHT, heading=0.0, cars=()):
    cars = np.asarray(cars, dtype=float).reshape(-1, 2)
    return indicators_to_dict(affordances(track, s, d, heading, cars[:, 0], cars[:, 1]))


def assert_in_lane_inactive(v):
    for name in ("toMarking_LL", "toMarking_ML", "toMarking_MR", "toMarking_RR", "dist_LL", "dist_MM", "dist_RR"):
        assert v[name] == INACTIVE[name], name


def assert_on_marking_inactive(v):
    for name in ("toMarking_L", "toMarking_M", "toMarking_R", "dist_L", "dist_R"):
        assert v[name] == INACTIVE[name], name


def test_inactive_values_are_the_documented_ones():
    assert INACTIVE == {"toMarking_LL": -9.5, "toMarking_ML": -5.5, "toMarking_MR": 5.5, "toMarking_RR": 9.5,
                        "dist_LL": 75, "dist_MM": 75, "dist_RR": 75, "toMarking_L": -7, "toMarking_M": 3.5,
                        "toMarking_R": 7, "dist_L": 75, "dist_R": 75}
    assert INDICATORS[:5] == ("angle", "toMarking_LL", "toMarking_ML", "toMarking_MR", "toMarking_RR")
    assert INDICATORS[-1] == "fast" and len(INDICATORS) == 14


# --- angle -----------------------------------------------------------------------------------------------------
def test_angle_is_tangent_minus_yaw_negative_when_car_turned_left(tracks):
    assert ind(tracks[3], 0.0, heading=0.1)["angle"] == pytest.approx(-0.1)
    assert ind(tracks[3], 0.0, heading=-0.25)["angle"] == pytest.approx(0.25)


def test_angle_wraps_into_minus_pi_pi(tracks):
    assert ind(tracks[3], 0.0, heading=3.5)["angle"] == pytest.approx(2 * math.pi - 3.5)
    assert ind(tracks[3], 0.0, heading=-math.pi)["angle"] == pytest.approx(math.pi)


# --- in-lane system --------------------------------------------------------------------------------------------
def test_in_lane_three_lane_centre_lane(tracks):
    d = 0.3
    v = ind(tracks[3], d)
    assert v["toMarking_ML"] == pytest.approx(d - 2)
    assert v["toMarking_MR"] == pytest.approx(d + 2)
    assert v["toMarking_LL"] == pytest.approx(d - 6)
    assert v["toMarking_RR"] == pytest.approx(d + 6)


def test_in_lane_three_lane_right_lane_has_no_right_neighbour(tracks):
    d = -4.2
    v = ind(tracks[3], d)
    assert v["toMarking_LL"] == pytest.approx(d - 2)
    assert v["toMarking_ML"] == pytest.approx(d + 2)
    assert v["toMarking_MR"] == pytest.approx(d + 6)
    assert v["toMarking_RR"] == 9.5
    assert v["dist_RR"] == 75


def test_in_lane_three_lane_left_lane_has_no_left_neighbour(tracks):
    d = 4.0
    v = ind(tracks[3], d)
    assert v["toMarking_LL"] == -9.5 and v["dist_LL"] == 75
    assert v["toMarking_ML"] == pytest.approx(-2.0)
    assert v["toMarking_MR"] == pytest.approx(2.0)
    assert v["toMarking_RR"] == pytest.approx(6.0)
    assert v["dist_MM"] == 60 and v["dist_RR"] == 60


def test_in_lane_four_lanes_second_lane(tracks):
    d = 2.5  # lane 1 of 4: markings +8, +4, 0, -4, -8
    v = ind(tracks[4], d)
    assert (v["toMarking_LL"], v["toMarking_ML"], v["toMarking_MR"], v["toMarking_RR"]) == pytest.approx(
        (d - 8, d - 4, d, d + 4))


def test_in_lane_one_lane(tracks):
    v = ind(tracks[1], 0.4)
    assert v["toMarking_ML"] == pytest.approx(0.4 - 2) and v["toMarking_MR"] == pytest.approx(0.4 + 2)
    assert v["toMarking_LL"] == -9.5 and v["toMarking_RR"] == 9.5
    assert v["dist_LL"] == 75 and v["dist_RR"] == 75 and v["dist_MM"] == 60


def test_in_lane_active_up_to_half_width_minus_half_metre(tracks):
    assert ind(tracks[3], 1.5)["toMarking_ML"] == pytest.approx(-0.5)   # |d - c| = 1.5: still active
    assert ind(tracks[3], -1.5)["toMarking_MR"] == pytest.approx(0.5)
    assert_in_lane_inactive(ind(tracks[3], 1.6))                         # 1.6 > 1.5: inactive


# --- on-marking system ---------------------------------------------------------------------------------------------
def test_on_marking_internal_marking_three_lanes(tracks):
    d = 2.9  # 0.9 m left of marking m_1 = +2
    v = ind(tracks[3], d)
    assert v["toMarking_M"] == pytest.approx(d - 2)
    assert v["toMarking_L"] == pytest.approx(d - 6)
    assert v["toMarking_R"] == pytest.approx(d + 2)


def test_on_marking_band_is_one_metre(tracks):
    assert ind(tracks[3], 2 + 1.0)["toMarking_M"] == pytest.approx(1.0)
    assert_on_marking_inactive(ind(tracks[3], 2 + 1.1))
    assert_on_marking_inactive(ind(tracks[3], -2 - 1.1))


def test_on_marking_band_is_1_2_m_on_two_lane_roads(tracks):
    assert ind(tracks[2], 1.15)["toMarking_M"] == pytest.approx(1.15)   # m_1 = 0 on two lanes
    assert ind(tracks[2], -1.2)["toMarking_M"] == pytest.approx(-1.2)
    assert_on_marking_inactive(ind(tracks[2], 1.25))
    assert_on_marking_inactive(ind(tracks[3], 2 + 1.15))                 # three lanes keep h = 1.0


def test_on_marking_left_edge_band(tracks):
    for d in (5.0, 6.0, 7.9):  # from h inside the road to 2 m outside it (m_0 = +6)
        v = ind(tracks[3], d)
        assert v["toMarking_L"] == -7 and v["dist_L"] == 75
        assert v["toMarking_M"] == pytest.approx(d - 6)
        assert v["toMarking_R"] == pytest.approx(d - 2)
    assert_on_marking_inactive(ind(tracks[3], 4.95))
    assert_on_marking_inactive(ind(tracks[3], 8.1))


def test_on_marking_right_edge_band(tracks):
    for d in (-5.0, -6.0, -7.9):  # m_3 = -6
        v = ind(tracks[3], d)
        assert v["toMarking_R"] == 7 and v["dist_R"] == 75
        assert v["toMarking_M"] == pytest.approx(d + 6)
        assert v["toMarking_L"] == pytest.approx(d + 2)
    assert_on_marking_inactive(ind(tracks[3], -4.95))
    assert_on_marking_inactive(ind(tracks[3], -8.1))


def test_on_marking_one_lane_edges(tracks):
    v = ind(tracks[1], 1.5)  # left edge band of a 4 m single lane: [1, 4]
    assert v["toMarking_L"] == -7 and v["toMarking_M"] == pytest.approx(-0.5)
    assert v["toMarking_R"] == pytest.approx(3.5) and v["dist_L"] == 75 and v["dist_R"] == 60
    assert_on_marking_inactive(ind(tracks[1], 0.9))


# --- overlap ----------------------------------------------------------------------------------------------------------
def test_overlap_both_systems_active(tracks):
    d = 2.6  # left lane (c_0 = 4, |d - c| = 1.4) and 0.6 m from m_1 = 2
    v = ind(tracks[3], d)
    assert v["toMarking_ML"] == pytest.approx(d - 6) and v["toMarking_MR"] == pytest.approx(d - 2)
    assert v["toMarking_M"] == pytest.approx(d - 2) and v["toMarking_L"] == pytest.approx(d - 6)


@pytest.mark.parametrize("lanes", [1, 2, 3, 4])
def test_every_point_of_road_and_verges_is_covered(tracks, lanes):
    tr = tracks[lanes]
    for d in np.arange(-tr.half_width - 2.0, tr.half_width + 2.0 + 1e-9, 0.01):
        v = ind(tr, float(d))
        in_lane = v["toMarking_ML"] != INACTIVE["toMarking_ML"]
        on_marking = v["toMarking_M"] != INACTIVE["toMarking_M"]
        assert in_lane or on_marking, d


def test_overlap_band_width(tracks):
    def both(tr, d):
        v = ind(tr, d)
        return v["toMarking_ML"] != -5.5 and v["toMarking_M"] != 3.5
    ds = np.arange(0.0, 2.0, 0.001)  # one overlap band on each side of a marking; count the one below m_1
    # 3 lanes: overlap between c_1 + 1.5 = 1.5 and m_1 - 1 = 1.0 -> 0.5 m wide
    assert sum(both(tracks[3], float(d)) for d in ds) * 0.001 == pytest.approx(0.5, abs=0.005)
    # 2 lanes: from c_0 - 1.5 = 0.5 to m_1 + 1.2 = 1.2 -> 0.7 m wide
    assert sum(both(tracks[2], float(d)) for d in ds) * 0.001 == pytest.approx(0.7, abs=0.005)


# --- gaps -------------------------------------------------------------------------------------------------------------
def test_gap_is_centre_to_centre_along_the_centreline(tracks):
    v = ind(tracks[3], 0.0, cars=[(S_STRAIGHT + 23.5, 0.5)])
    assert v["dist_MM"] == pytest.approx(23.5)


def test_gap_60_when_lane_exists_but_is_empty_or_far(tracks):
    assert ind(tracks[3], 0.0)["dist_MM"] == 60
    assert ind(tracks[3], 0.0, cars=[(S_STRAIGHT + 75.0, 0.0)])["dist_MM"] == 60
    assert ind(tracks[3], 0.0, cars=[(S_STRAIGHT + 59.0, 0.0)])["dist_MM"] == pytest.approx(59.0)


def test_only_cars_strictly_ahead_count(tracks):
    v = ind(tracks[3], 0.0, cars=[(S_STRAIGHT - 5.0, 0.0), (S_STRAIGHT, 0.0)])
    assert v["dist_MM"] == 60


def test_nearest_car_ahead_per_lane(tracks):
    cars = [(S_STRAIGHT + 40, 4.0), (S_STRAIGHT + 12, 3.0), (S_STRAIGHT + 30, 0.0), (S_STRAIGHT + 8, -4.0),
            (S_STRAIGHT + 50, -4.5)]
    v = ind(tracks[3], 0.0, cars=cars)
    assert (v["dist_LL"], v["dist_MM"], v["dist_RR"]) == pytest.approx((12.0, 30.0, 8.0))


def test_gap_75_for_lanes_that_do_not_exist_and_inactive_systems(tracks):
    v = ind(tracks[3], -4.0, cars=[(S_STRAIGHT + 10, -4.0)])
    assert v["dist_RR"] == 75 and v["dist_MM"] == pytest.approx(10.0)
    v = ind(tracks[3], 1.7, cars=[(S_STRAIGHT + 10, 0.0)])  # 1.7 m off the centre lane: in-lane inactive
    assert v["dist_MM"] == 75


def test_on_marking_gaps_are_the_lanes_either_side_of_the_marking(tracks):
    cars = [(S_STRAIGHT + 20, 4.0), (S_STRAIGHT + 35, 0.0), (S_STRAIGHT + 9, -4.0)]
    v = ind(tracks[3], 2.3, cars=cars)    # on m_1: left lane 0, right lane 1
    assert (v["dist_L"], v["dist_R"]) == pytest.approx((20.0, 35.0))
    v = ind(tracks[3], -2.3, cars=cars)   # on m_2: left lane 1, right lane 2
    assert (v["dist_L"], v["dist_R"]) == pytest.approx((35.0, 9.0))


def test_cars_off_the_road_count_in_the_outermost_lane(tracks):
    v = ind(tracks[3], -4.0, cars=[(S_STRAIGHT + 15, -7.5)])
    assert v["dist_MM"] == pytest.approx(15.0)
    v = ind(tracks[3], 4.0, cars=[(S_STRAIGHT + 16, 7.0)])
    assert v["dist_MM"] == pytest.approx(16.0)


def test_wrap_around_at_the_seam(tracks):
    tr = tracks[3]
    v = ind(tr, 0.0, s=tr.length - 10.0, cars=[(15.0, 0.0)])
    assert v["dist_MM"] == pytest.approx(25.0)
    v = ind(tr, 0.0, s=10.0, cars=[(tr.length - 5.0, 0.0)])  # 15 m behind across the seam
    assert v["dist_MM"] == 60


# --- fast -------------------------------------------------------------------------------------------------------------
def test_fast_on_a_long_straight_ahead(tracks):
    assert ind(tracks[3], 0.0, s=100.0)["fast"] == 1.0     # 400 m of straight ahead
    assert ind(tracks[3], 0.0, s=439.0)["fast"] == 1.0     # 61 m ahead
    assert ind(tracks[3], 0.0, s=441.0)["fast"] == 0.0     # 59 m ahead
    assert ind(tracks[3], 0.0, s=600.0)["fast"] == 0.0     # on the arc


def test_fast_counts_consecutive_straights_as_one():
    spec = {"name": "two-straights", "lanes": 2, "segments": [
        {"type": "straight", "length": 40}, {"type": "straight", "length": 40},
        {"type": "arc", "radius": 50, "angle_deg": 180, "turn": "left"},
        {"type": "straight", "length": 80}, {"type": "arc", "radius": 50, "angle_deg": 180, "turn": "left"}]}
    tr = load_track(spec)
    assert ind(tr, 0.0, s=10.0)["fast"] == 1.0   # 70 m of straight ahead across the segment boundary
    assert ind(tr, 0.0, s=25.0)["fast"] == 0.0   # 55 m


def test_fast_continues_across_the_seam():
    spec = {"name": "seam", "lanes": 2, "segments": [
        {"type": "straight", "length": 30}, {"type": "arc", "radius": 50, "angle_deg": 180, "turn": "left"},
        {"type": "straight", "length": 80}, {"type": "arc", "radius": 50, "angle_deg": 180, "turn": "left"},
        {"type": "straight", "length": 50}]}
    tr = load_track(spec)
    assert ind(tr, 0.0, s=tr.length - 40.0)["fast"] == 1.0   # 40 m to the seam + 30 m after it
    assert ind(tr, 0.0, s=tr.length - 20.0)["fast"] == 0.0   # 50 m


# --- extras -----------------------------------------------------------------------------------------------------------
def test_ground_truth_extras(tracks):
    tr = tracks[3]
    x, y, h = tr.pose(S_STRAIGHT, -4.0)
    gt = ground_truth(tr, np.array([x, y, h + 0.05, S_STRAIGHT, -4.0]), 0.05, 17.5,
                      np.array([[0, 0, 0, S_STRAIGHT + 30, -4.0]]), [4.6], [12.0])
    assert gt.lanes_left == 2 and gt.lanes == 3 and gt.speed == 17.5
    assert gt.in_lane and not gt.on_marking
    assert gt.indicators[6] == pytest.approx(30.0)   # dist_MM
    assert gt.as_dict()["angle"] == pytest.approx(-0.05)


# --- beside and behind (the extended label set) ------------------------------------------------------------------
HOST = 4.6    # [m] the host car's length
V_HOST = 20.0  # [m/s]


def rear(track, d, cars=(), s=S_STRAIGHT, host_length=HOST, speed=V_HOST):
    """{dist_LB, dist_RB, closing_LB, closing_RB} for cars given as (s, d, length, speed)."""
    cars = np.asarray(cars, dtype=float).reshape(-1, 4)
    v = rear_indicators(track, s, d, host_length, speed, cars[:, 0], cars[:, 1], cars[:, 2], cars[:, 3])
    return dict(zip(("dist_LB", "dist_RB", "closing_LB", "closing_RB"), v.tolist()))


def test_rear_labels_are_declared_after_everything_else_with_their_maps():
    assert HIGHWAY.truth_names[-4:] == ("dist_LB", "dist_RB", "closing_LB", "closing_RB")
    assert HIGHWAY.truth_names[:len(INDICATORS)] == INDICATORS and HIGHWAY.index("off_road") == 26
    assert LABEL_SETS["paper"] == PAPER_INDICATORS == HIGHWAY.targets
    assert LABEL_SETS["extended"] == INDICATORS + ("lanes_left", "dist_LB", "dist_RB", "closing_LB", "closing_RB")
    assert HIGHWAY.label_set("extended") == LABEL_SETS["extended"]
    # rear gaps 0 .. 100 m and closing speeds -20 .. 20 m/s both map to 0.1 .. 0.9
    assert HIGHWAY.normalise([0.0, 100.0, -20.0, 20.0], ["dist_LB", "dist_RB", "closing_LB", "closing_RB"]) == \
        pytest.approx([0.1, 0.9, 0.1, 0.9], abs=1e-6)
    assert HIGHWAY.label("dist_LB").inactive == 100.0 and HIGHWAY.label("closing_RB").inactive == 0.0


def test_rear_a_car_exactly_alongside_reads_0_and_its_closing_speed(tracks):
    v = rear(tracks[3], 0.0, cars=[(S_STRAIGHT, 4.0, 4.1, 23.0), (S_STRAIGHT, -4.0, 4.9, 18.5)])
    assert v == pytest.approx({"dist_LB": 0.0, "dist_RB": 0.0, "closing_LB": 3.0, "closing_RB": -1.5})


def test_rear_a_car_overlapping_the_hosts_length_reads_0_whether_its_centre_is_ahead_or_behind(tracks):
    half = (HOST + 4.4) / 2   # 4.5 m: centres closer than this overlap along the track
    for ds in (half - 0.01, 2.0, -2.0, -(half - 0.01)):
        assert rear(tracks[3], 0.0, cars=[(S_STRAIGHT + ds, 4.0, 4.4, 20.0)])["dist_LB"] == 0.0, ds


def test_rear_a_car_just_behind_reads_the_bumper_gap(tracks):
    # rear bumper of the host at s - 2.3, front bumper of a 4.1 m car at its s + 2.05: 0.5 m apart
    v = rear(tracks[3], 0.0, cars=[(S_STRAIGHT - 2.3 - 2.05 - 0.5, -4.0, 4.1, 26.0)])
    assert v["dist_RB"] == pytest.approx(0.5) and v["closing_RB"] == pytest.approx(6.0)
    assert v["dist_LB"] == 100.0 and v["closing_LB"] == 0.0
    v = rear(tracks[3], 0.0, cars=[(S_STRAIGHT - 30.0, 4.0, 4.6, 15.0)])
    assert v["dist_LB"] == pytest.approx(30.0 - 4.6) and v["closing_LB"] == pytest.approx(-5.0)


def test_rear_a_car_wholly_ahead_does_not_count(tracks):
    half = (HOST + 4.4) / 2
    v = rear(tracks[3], 0.0, cars=[(S_STRAIGHT + half, 4.0, 4.4, 30.0), (S_STRAIGHT + 20, -4.0, 4.4, 30.0)])
    assert v == {"dist_LB": 100.0, "dist_RB": 100.0, "closing_LB": 0.0, "closing_RB": 0.0}


def test_rear_range_is_100_m_beyond_it_the_inactive_values(tracks):
    v = rear(tracks[3], 0.0, cars=[(S_STRAIGHT - 4.6 - 99.9, 4.0, 4.6, 30.0)])
    assert v["dist_LB"] == pytest.approx(99.9) and v["closing_LB"] == pytest.approx(10.0)
    v = rear(tracks[3], 0.0, cars=[(S_STRAIGHT - 4.6 - 100.1, 4.0, 4.6, 30.0)])
    assert (v["dist_LB"], v["closing_LB"]) == (100.0, 0.0)


def test_rear_nearest_car_per_lane_and_the_faster_of_two_alongside(tracks):
    cars = [(S_STRAIGHT - 20, 4.0, 4.6, 25.0), (S_STRAIGHT - 10, 4.0, 4.6, 21.0), (S_STRAIGHT - 40, 4.0, 4.6, 35.0),
            (S_STRAIGHT - 1, -4.0, 4.6, 19.0), (S_STRAIGHT + 1, -4.0, 4.6, 24.0)]
    v = rear(tracks[3], 0.0, cars=cars)
    assert v == pytest.approx({"dist_LB": 10.0 - 4.6, "closing_LB": 1.0, "dist_RB": 0.0, "closing_RB": 4.0})


def test_rear_only_the_lanes_beside_count_not_the_hosts_own_or_two_away(tracks):
    cars = [(S_STRAIGHT - 10, 0.0, 4.6, 30.0), (S_STRAIGHT - 10, -6.0, 4.6, 30.0)]   # 4 lanes: lanes 2 and 3
    v = rear(tracks[4], 1.5, cars=cars)   # host in lane 1 (d 1.5): left lane 0, right lane 2
    assert v["dist_RB"] == pytest.approx(10.0 - 4.6) and v["dist_LB"] == 100.0
    v = rear(tracks[4], 1.5, cars=[(S_STRAIGHT - 10, 2.0, 4.6, 30.0)])                # same lane as the host
    assert v == {"dist_LB": 100.0, "dist_RB": 100.0, "closing_LB": 0.0, "closing_RB": 0.0}


def test_rear_lanes_that_do_not_exist_read_the_inactive_values(tracks):
    cars = [(S_STRAIGHT - 10, 4.0, 4.6, 30.0), (S_STRAIGHT - 10, -4.0, 4.6, 30.0)]
    left = rear(tracks[3], 4.0, cars=cars)     # leftmost lane: no lane to the left
    assert (left["dist_LB"], left["closing_LB"]) == (100.0, 0.0) and left["dist_RB"] == 100.0
    right = rear(tracks[3], -4.0, cars=cars)   # rightmost lane
    assert (right["dist_RB"], right["closing_RB"]) == (100.0, 0.0) and right["dist_LB"] == 100.0
    one = rear(tracks[1], 0.0, cars=[(S_STRAIGHT - 5, 0.5, 4.6, 30.0)])
    assert one == {"dist_LB": 100.0, "dist_RB": 100.0, "closing_LB": 0.0, "closing_RB": 0.0}
    two = rear(tracks[2], -2.0, cars=[(S_STRAIGHT - 10, 2.0, 4.6, 22.0)])
    assert two["dist_LB"] == pytest.approx(5.4) and two["closing_LB"] == pytest.approx(2.0)
    assert (two["dist_RB"], two["closing_RB"]) == (100.0, 0.0)


def test_rear_lanes_follow_lanes_left_on_a_marking_too(tracks):
    cars = [(S_STRAIGHT - 10, 4.0, 4.6, 30.0), (S_STRAIGHT - 10, 0.0, 4.6, 25.0)]
    v = rear(tracks[3], 2.3, cars=cars)   # astride m_1 = 2, centre in lane 0: the lane to its right is lane 1
    assert v["dist_LB"] == 100.0 and v["dist_RB"] == pytest.approx(5.4) and v["closing_RB"] == pytest.approx(5.0)
    v = rear(tracks[3], 2.0, cars=cars)   # exactly on m_1: in lane 1, lane 0 on its left
    assert v["dist_LB"] == pytest.approx(5.4) and v["closing_LB"] == pytest.approx(10.0)


def test_rear_gaps_wrap_across_the_seam_and_off_road_cars_count_outermost(tracks):
    tr = tracks[3]
    v = rear(tr, 0.0, s=3.0, cars=[(tr.length - 12.0, 4.0, 4.6, 25.0)])   # 15 m behind across the seam
    assert v["dist_LB"] == pytest.approx(15.0 - 4.6)
    v = rear(tr, 0.0, cars=[(S_STRAIGHT - 8.0, -7.5, 4.6, 25.0)])         # on the right verge: lane 2
    assert v["dist_RB"] == pytest.approx(8.0 - 4.6)


def test_rear_uses_the_hosts_own_length(tracks):
    v = rear(tracks[3], 0.0, cars=[(S_STRAIGHT - 10.0, 4.0, 4.0, 20.0)], host_length=6.0)
    assert v["dist_LB"] == pytest.approx(10.0 - 5.0)


def test_ground_truth_carries_the_rear_labels_into_the_record(tracks):
    tr = tracks[3]
    x, y, h = tr.pose(S_STRAIGHT, 0.0)
    cars = np.array([[0, 0, 0, S_STRAIGHT - 12.0, 4.0], [0, 0, 0, S_STRAIGHT + 1.0, -4.0]])
    gt = ground_truth(tr, np.array([x, y, h, S_STRAIGHT, 0.0]), 0.0, 18.0, cars, [4.4, 4.9], [24.0, 17.0])
    d = gt.as_dict()
    assert (d["dist_LB"], d["dist_RB"]) == pytest.approx((12.0 - 4.5, 0.0))
    assert (d["closing_LB"], d["closing_RB"]) == pytest.approx((6.0, -1.0))
    rec = HIGHWAY.unpack(truth_record(gt, False, False))
    assert {n: rec[n] for n in ("dist_LB", "dist_RB", "closing_LB", "closing_RB")} == pytest.approx(
        {n: d[n] for n in ("dist_LB", "dist_RB", "closing_LB", "closing_RB")})
    assert rec["lanes_left"] == 1 and rec["dist_RR"] == pytest.approx(1.0)   # the same car is ahead, 1 m
