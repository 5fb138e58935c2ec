"""The rear-view mirror (sim/mirror.py, docs/rendering.md): where it sits, that it shows what is behind flipped as a
mirror does (left lane on the left), that the front view around it is untouched, and that the declaration says so."""
import numpy as np
import pytest

from core.declaration import Camera, DeclarationError, WorldDeclaration
from core.worlds.highway import HIGHWAY
from sim.highway.scenario import CarSpec, Scenario
from sim.highway.vehicle import VehicleState
from sim.highway.world import World, WorldConfig
from sim.mirror import BORDER, INSET_FLAGS, RearMirror, SideViews, inset_name, inset_options
from sim.track import load_track

HOST_S = 100.0


def frame_of(cars, mirror=True, sides=False):
    """The host at s = 100 m in the middle of three lanes (d = 0; d > 0 is left), standing; cars as (s, d)."""
    track = load_track("oval", lanes=3)
    scenario = Scenario(track, VehicleState(s=HOST_S, d=0.0), [CarSpec(s=s, d=d) for s, d in cars], seed=1)
    with World(WorldConfig(cars=0, mirror=mirror, side_views=sides), scenario=scenario) as world:
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


# --- the side views: the blind spot between the front view and the mirror ---------------------------------------

def side_glass(frame, side):
    top, left, h, w = SideViews(*frame.shape[:2]).rects[side]
    return frame[top + BORDER:top + h - BORDER, left + BORDER:left + w - BORDER]


def changed(region, cars, **where) -> float:
    """The share of a region's pixels (a function of the frame) that the cars change, with the side views on."""
    diff = np.abs(region(frame_of(cars, sides=True), **where).astype(int) -
                  region(frame_of([], sides=True), **where).astype(int)).sum(axis=-1)
    return float((diff > 0).mean())


def test_the_side_views_sit_below_the_mirror_at_the_frames_outer_edges():
    views = SideViews(210, 280)
    assert views.rects == ((58, 4, 32, 100), (58, 176, 32, 100))   # top, left, height, width
    top, _, h, _ = RearMirror(210, 280).rect
    assert views.rects[0][0] >= top + h and views.rects[0][0] + views.rects[0][2] < 99   # under it, above the horizon
    cam = views.camera
    assert (cam.width, cam.height) == (96, 28) and cam.hfov == pytest.approx(np.radians(90.0))


def test_side_composite_pastes_each_image_as_it_is_inside_a_border():
    views = SideViews(210, 280)
    cam = views.camera
    left = np.zeros((cam.height, cam.width, 3), np.uint8)
    left[:, : cam.width // 2] = (255, 0, 0)        # the left camera's left half: what lies behind, to the left
    right = np.full((cam.height, cam.width, 3), 9, np.uint8)
    frame = views.composite(np.full((210, 280, 3), 200, np.uint8), left, right)
    g = side_glass(frame, 0)
    assert (g[:, 0] == (255, 0, 0)).all() and (g[:, -1] == (0, 0, 0)).all()    # not flipped: a window
    assert (side_glass(frame, 1) == 9).all()
    top, x0, h, w = views.rects[1]
    assert (frame[top, x0:x0 + w] == (24, 24, 24)).all() and (frame[top - 1] == 200).all()
    assert (frame[top:top + h, 4 + 100:176] == 200).all()     # the middle, where the lane ahead lies, untouched


@pytest.mark.parametrize("d, side", [(4.0, 0), (-4.0, 1)])
def test_a_car_level_with_the_host_shows_in_its_sides_view_and_in_no_other(d, side):
    """The blind spot: the car's length overlaps the host's, so the mirror and the front view miss it."""
    cars = [(HOST_S + 0.5, d)]
    assert changed(side_glass, cars, side=side) > 0.2
    assert changed(side_glass, cars, side=1 - side) == 0.0
    assert changed(glass, cars) == 0.0
    assert changed(lambda f: f[100:], cars) == 0.0        # the front view below the horizon


def test_the_left_view_shows_ahead_on_its_right_and_behind_on_its_left():
    ahead, behind = (side_glass(frame_of([(HOST_S + s, 4.0)], sides=True), 0) for s in (3.0, -3.0))
    empty = side_glass(frame_of([], sides=True), 0)
    cols = [np.flatnonzero(np.abs(v.astype(int) - empty.astype(int)).sum(axis=(0, 2))) / empty.shape[1]
            for v in (ahead, behind)]
    assert cols[0].mean() > 0.5 > cols[1].mean()


def test_the_frame_outside_the_side_views_is_the_mirrors_frame():
    cars = [(130.0, 4.0), (85.0, -4.0), (HOST_S, 4.0)]
    with_sides, mirror_only = frame_of(cars, sides=True), frame_of(cars)
    outside = np.ones((210, 280), bool)
    for top, left, h, w in SideViews(210, 280).rects:
        outside[top:top + h, left:left + w] = False
    assert np.array_equal(with_sides[outside], mirror_only[outside])
    assert not np.array_equal(with_sides[~outside], mirror_only[~outside])


def test_the_inset_names_and_the_world_options_agree():
    for inset, (mirror, sides) in INSET_FLAGS.items():
        assert inset_name(mirror, sides) == inset
        assert WorldConfig(**inset_options(inset)).inset == inset
    assert (frame_of([], mirror=False, sides=True) == frame_of([], sides=True)).all()
    assert inset_name(False, True) == "mirror+sides"      # the side views bring the mirror
    track = load_track("oval", lanes=3)
    with World(WorldConfig(cars=0, mirror=True, side_views=True, render=False),
               scenario=Scenario(track, VehicleState(s=HOST_S), [], seed=1)) as world:
        assert world.declaration.cameras[0].inset == "mirror+sides"
