"""The rear-view mirror (sim/mirror.py, docs/rendering.md): where it sits, that it shows what is behind flipped as a
mirror does (left lane on the left), that the front view around it is untouched, and that the declaration says so."""
import numpy as np
import pytest

from core.declaration import Camera, DeclarationError, WorldDeclaration
from core.worlds.highway import HIGHWAY
from sim.highway.scenario import CarSpec, Scenario
from sim.highway.vehicle import VehicleState
from sim.highway.world import World, WorldConfig
from sim.mirror import BORDER, RearMirror
from sim.track import load_track

HOST_S = 100.0


def frame_of(cars, mirror=True):
    """The host at s = 100 m in the middle of three lanes (d = 0; d > 0 is left), standing; cars as (s, d)."""
    track = load_track("oval", lanes=3)
    scenario = Scenario(track, VehicleState(s=HOST_S, d=0.0), [CarSpec(s=s, d=d) for s, d in cars], seed=1)
    with World(WorldConfig(cars=0, mirror=mirror), scenario=scenario) as world:
        return world.observe(render=True).frame


def glass(frame):
    top, left, h, w = RearMirror(*frame.shape[:2]).rect
    return frame[top + BORDER:top + h - BORDER, left + BORDER:left + w - BORDER]


def changed_columns(cars):
    """Columns of the mirror's glass where the cars change the picture, as a share of its width (0 left, 1 right)."""
    diff = np.abs(glass(frame_of(cars)).astype(int) - glass(frame_of([])).astype(int)).sum(axis=(0, 2))
    cols = np.flatnonzero(diff)
    return cols / diff.size


def test_the_mirror_sits_at_the_top_centre_of_the_default_frame():
    mirror = RearMirror(210, 280)
    assert mirror.rect == (4, 28, 52, 224)     # top, left, height, width: centred, above the horizon (row ~99)
    cam = mirror.camera
    assert (cam.width, cam.height) == (220, 48)
    assert cam.hfov == pytest.approx(np.radians(90.0))


def test_composite_flips_the_rear_image_left_to_right_inside_a_border():
    mirror = RearMirror(210, 280)
    cam = mirror.camera
    rear = np.zeros((cam.height, cam.width, 3), np.uint8)
    rear[:, : cam.width // 2] = (255, 0, 0)      # the rear camera's left half: what lies to the host's right
    frame = mirror.composite(np.full((210, 280, 3), 200, np.uint8), rear)
    g = glass(frame)
    assert (g[:, -1] == (255, 0, 0)).all() and (g[:, 0] == (0, 0, 0)).all()
    top, left, h, w = mirror.rect
    assert (frame[top, left:left + w] == (24, 24, 24)).all()          # the dark border
    assert (frame[top - 1] == 200).all() and (frame[top + h] == 200).all()   # nothing outside it touched


def test_the_front_view_around_the_mirror_is_the_one_without_it():
    cars = [(130.0, 4.0), (80.0, -4.0)]
    with_mirror, without = frame_of(cars), frame_of(cars, mirror=False)
    top, left, h, w = RearMirror(210, 280).rect
    outside = np.ones((210, 280), bool)
    outside[top:top + h, left:left + w] = False
    assert np.array_equal(with_mirror[outside], without[outside])
    assert not np.array_equal(with_mirror[~outside], without[~outside])


def test_a_car_behind_in_the_left_lane_shows_on_the_left_of_the_mirror():
    cols = changed_columns([(85.0, 4.0)])
    assert cols.size and cols.max() < 0.5


def test_a_car_behind_in_the_right_lane_shows_on_the_right_of_the_mirror():
    cols = changed_columns([(85.0, -4.0)])
    assert cols.size and cols.min() > 0.5


def test_a_car_ahead_does_not_show_in_the_mirror():
    assert changed_columns([(120.0, 0.0), (115.0, 4.0)]).size == 0


def test_the_world_declares_its_inset_and_a_declaration_without_one_is_unchanged():
    track = load_track("oval", lanes=3)
    scenario = Scenario(track, VehicleState(s=HOST_S), [], seed=1)
    with World(WorldConfig(cars=0, mirror=True, render=False), scenario=scenario) as world:
        decl = world.declaration
    assert decl.cameras[0].inset == "mirror" and decl.cameras[0].shape == (210, 280, 3)
    assert WorldDeclaration.from_json(decl.to_json()) == decl
    assert decl.fingerprint() != HIGHWAY.fingerprint()        # mirror frames are other data
    assert "inset" not in HIGHWAY.to_json()["cameras"][0]      # older datasets and checkpoints read the same
    assert HIGHWAY.with_camera("front", 210, 280, "") is HIGHWAY


def test_an_unknown_inset_is_refused():
    with pytest.raises(DeclarationError, match="unknown inset 'periscope'"):
        Camera("front", 210, 280, inset="periscope")
