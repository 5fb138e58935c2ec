"""The world declaration's decisive steps (core/declaration.py), which `train --emphasis` weighs: checked, carried
by a declaration's JSON, left out of the fingerprint (they do not change what recorded data means), and the
highway's the Chen controller's own occupancy rule ahead and the lookout's safe gap behind."""
from dataclasses import replace

import pytest

from controller.highway.chen import ChenParams
from controller.highway.lookout import safe_gap
from core.declaration import DeclarationError, WorldDeclaration
from core.worlds.highway import HIGHWAY, HIGHWAY_WITHOUT_REAR, REAR, REAR_OCCUPIED


def test_the_highways_decisive_steps_are_a_near_car_ahead_in_the_host_or_a_neighbouring_lane_or_behind():
    ahead = {"dist_LL", "dist_MM", "dist_RR", "dist_L", "dist_R"}
    assert dict(HIGHWAY.decisive) == {**dict.fromkeys(ahead, 20.0), "dist_LB": 20.0, "dist_RB": 20.0}
    # one number, one owner: ahead, the Chen controller's occupancy rule
    assert {bound for n, bound in HIGHWAY.decisive if n in ahead} == {ChenParams().occupied_gap}


def test_a_near_car_behind_is_one_the_lookout_refuses_a_change_for():
    """The rear bound covers the lookout's safe gap for a car closing at up to 6 m/s at 15-20 m/s (and not for
    one at 8 m/s: a bound far beyond what the lookout asks would call every frame decisive)."""
    for speed in (15.0, 20.0):
        assert safe_gap(6.0, speed) <= REAR_OCCUPIED < safe_gap(8.0, speed)


def test_a_dataset_of_format_version_1_has_no_decisive_steps_behind():
    assert {n for n, _ in HIGHWAY_WITHOUT_REAR.decisive} == {n for n, _ in HIGHWAY.decisive} - set(REAR)


def test_decisive_steps_travel_with_the_declaration_but_not_in_its_fingerprint():
    assert WorldDeclaration.from_json(HIGHWAY.to_json()) == HIGHWAY
    plain = replace(HIGHWAY, decisive=())
    assert "decisive" not in plain.to_json()
    assert plain.fingerprint() == HIGHWAY.fingerprint()   # datasets made before still merge with new ones


@pytest.mark.parametrize("decisive", [(("dist_XX", 20.0),), (("dist_LL", float("nan")),), (("speed", 1.0),)])
def test_decisive_steps_name_labels_and_finite_bounds(decisive):
    with pytest.raises(DeclarationError, match="decisive steps"):
        replace(HIGHWAY, decisive=decisive)
