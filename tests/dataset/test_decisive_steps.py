"""The world declaration's decisive steps (core/declaration.py), which `train --set emphasis=W` weighs: checked, carried
by a declaration's JSON, left out of the fingerprint (they do not change what recorded data means), and the
highway's the Chen controller's own occupancy rule."""
from dataclasses import replace

import pytest

from controller.highway.chen import ChenParams
from core.declaration import DeclarationError, WorldDeclaration
from core.worlds.highway import HIGHWAY


def test_the_highways_decisive_steps_are_a_near_car_ahead_in_the_host_or_a_neighbouring_lane():
    assert dict(HIGHWAY.decisive) == {"dist_LL": 20.0, "dist_MM": 20.0, "dist_RR": 20.0, "dist_L": 20.0,
                                      "dist_R": 20.0}
    assert {bound for _, bound in HIGHWAY.decisive} == {ChenParams().occupied_gap}   # one number, one owner


def test_decisive_steps_travel_with_the_declaration_but_not_in_its_fingerprint():
    assert WorldDeclaration.from_json(HIGHWAY.to_json()) == HIGHWAY
    plain = replace(HIGHWAY, decisive=())
    assert "decisive" not in plain.to_json()
    assert plain.fingerprint() == HIGHWAY.fingerprint()   # datasets made before still merge with new ones


@pytest.mark.parametrize("decisive", [(("dist_XX", 20.0),), (("dist_LL", float("nan")),), (("speed", 1.0),)])
def test_decisive_steps_name_labels_and_finite_bounds(decisive):
    with pytest.raises(DeclarationError, match="decisive steps"):
        replace(HIGHWAY, decisive=decisive)
