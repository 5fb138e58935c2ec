"""A triangle with a corner exactly in the eye's plane (clip-space w = 0) is drawn as far as it can be, without an
error: a generated dataset once stopped at such a frame (a car's corner level with the camera of a side view)."""
import numpy as np

from sim.camera import CameraConfig
from sim.render.raster_objects import draw_body


def draw(verts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    cam = CameraConfig(width=80, height=60, pitch_deg=0.0)
    view = np.array(cam.view_matrix(0.0, 0.0, 0.0), dtype=np.float32).reshape(4, 4).T.copy()
    projection = np.array(cam.projection_matrix(), dtype=np.float32).reshape(4, 4).T.copy()
    eye, _ = cam.basis(0.0, 0.0, 0.0)
    img = np.zeros((60, 80, 3), dtype=np.uint8)
    zbuf = np.full((60, 80), -np.inf, dtype=np.float32)
    n = len(verts)
    everywhere = np.array([[0.0, 0.0, 0.0, 1e9]])   # one block of every triangle, in a sphere no view leaves out
    draw_body(img, zbuf, verts.astype(np.float32), np.tile(np.float32([0, 0, 1]), (n, 3, 1)),
              np.full((n, 3), 200.0, dtype=np.float32), np.zeros(n, dtype=np.bool_), np.array([[0, n]]), everywhere,
              0, 1, np.eye(4, dtype=np.float32), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3, dtype=np.float32),
              view, projection, eye.astype(np.float32),
              np.float32([0, 0, 1]), np.float32(0.6), np.float32(0.4), True)
    return img, zbuf


def test_a_corner_in_the_eyes_plane_divides_by_zero_without_raising():
    eye, (side, up, forward) = CameraConfig(width=80, height=60, pitch_deg=0.0).basis(0.0, 0.0, 0.0)
    level = eye + 1.0 * side    # beside the eye, in its plane: w = 0 exactly (a level camera keeps it exact)
    assert float(np.dot(level - eye, forward)) == 0.0
    ahead = [eye + 10 * forward - 1.0 * up, eye + 10 * forward - 0.5 * up - 2.0 * side]   # a plane off the eye
    for corners in ([level, *ahead], [level, ahead[1], ahead[0]]):   # both windings: one is a front face
        draw(np.array([corners]))
    # a triangle wholly ahead of the eye, beside it, is drawn: the camera sees
    img, zbuf = draw(np.array([[ahead[0] + 0.5 * up, ahead[1], ahead[0] - 1.0 * side + 1.5 * up],
                               [ahead[0] + 0.5 * up, ahead[0] - 1.0 * side + 1.5 * up, ahead[1]]]))
    assert np.isfinite(zbuf).any() and img.any()
