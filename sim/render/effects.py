"""A named condition drawn over the frames of a Geometry (sim/render/conditions.py), whatever renderer drew them,
from the frame and its depth:

- the ground (where no object was drawn and the ray goes down): the night's darkness and the host's headlights, the
  fog, all known from the pixel alone and computed once (sim/render/effect_kernels.py `ground`);
- the objects (a finite depth): the same from their distance (`objects`, found between each row's first and last
  finite depth); at night the street lamps' pools light the ground and the objects near them (`pools`); a wet road
  mirrors the objects standing on it (`objects` too, once they are drawn);
- lights over the rest (sim/render/light_kernels.py): the cars' tail and head lights and the lamps, the sun's glare
  and its disc, the rain's streaks;
- the sky is left as the renderer drew it, and the low sun's warm light is drawn by the renderer too: the world's
  Look for the condition gives them their colours (Look.tint the cars').

Effects builds their tables once; a frame's effects are one compiled call (sim/render/light_kernels.py `draw`).
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from sim.render.conditions import CarLights, Condition, Geometry, Lamps
from sim.render.effect_kernels import STEP, beams
from sim.render.light_kernels import draw

NO_DEPTH = np.zeros((0, 0), dtype=np.float32)
NO_CARS = (np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64))
STREAK_RGB = np.array([205.0, 210.0, 218.0])   # rain streaks: lit drops against the sky
TAIL_RGB, HEAD_RGB = np.array([255.0, 38.0, 26.0]), np.array([255.0, 246.0, 222.0])
HEADLIGHT_RGB = np.array([0.75, 0.72, 0.66])   # the host's beams: warm white, the road near them lit to 3/4 of day
GLARE_WIDTH = 0.008   # 1 - cos of the angle from the sun where its glare falls by e (about 7 degrees)
SUN_DISC = 1.5e-4     # 1 - cos of the sun's apparent radius, a little over its 0.27 degrees: a pixel or two
MIRRORED = 2.0        # [m] a wet road mirrors what stands up to this high on it (cars; not the crowns of trees)


class Effects:
    """Draws `condition` over the frames of `geometry`. road_rgb: the asphalt's colour as the renderers draw it
    (a wet road mirrors where the asphalt shows); headlight: the host's low beams (x, z [m] of their source in the
    car frame); seed: the rain's streaks; lamps, car_lights: what lights there are (None: none)."""

    def __init__(self, condition: Condition, geometry: Geometry, road_rgb, seed: int,
                 headlight: tuple[float, float] = (1.0, 0.65), lamps: Lamps | None = None,
                 car_lights: CarLights | None = None, lamp_reach: float = 16.0):
        self.condition, self.geometry = c, g = condition, geometry
        self.lamps = lamps if c.night >= 0 and c.street_lights > 0 and lamps is not None and len(lamps.pools) \
            else None
        self.car_lights = car_lights if car_lights is not None and car_lights.strength > 0 else None
        self._lamp_reach = lamp_reach
        self._road = np.asarray(road_rgb, dtype=np.int64)
        self._beam = np.array([headlight[0], headlight[1], max(c.headlight_reach, 1e-3), -0.004, 0.04, 0.6])
        self._dark = np.full(3, c.night if c.night >= 0 else 1.0, dtype=np.float32)
        self._gain = (HEADLIGHT_RGB if c.night >= 0 else np.zeros(3)).astype(np.float32)
        self._lamp_rgb = np.asarray(c.lamp_rgb, dtype=np.float64) * c.street_lights
        self._lamp_glow = np.asarray(c.lamp_rgb, dtype=np.float64) * 255.0
        self._density, self._sun = c.density, c.sun
        self._streak = 1.0 if c.wetness else 0.0   # a wet road streaks the lights' reflections
        self._fog_rgb = (np.asarray(c.fog_rgb, dtype=np.float64) * 255.0).astype(np.float32)
        d = np.arange(int(400 * STEP) + 1) / STEP   # the distance tables, STEP entries a metre
        fall = 1.0 / (1.0 + (d / self._beam[2]) ** 2) if c.night >= 0 else np.zeros(1)   # as falloff() has it
        self._fall = fall.astype(np.float32)
        self._fog_table = (np.exp(-c.density * d) if c.density > 0 else np.ones(1)).astype(np.float32)
        self._view = g.view.reshape(-1)
        self._border = np.flatnonzero(self._view < 0)
        self._statics()
        self._rows, self._spots = self._ground_rows()
        self._contact, self._wetness = self._wet_road()
        self._near = mirrored_depths(self._contact, g.view.shape[0], MIRRORED * g.cams[0, 13])
        self._sprite = glare_sprite(c.glare, g.cams[0, 12]) if c.glare > 0 else np.zeros((0, 0), np.float32)
        texture = rain_streaks(g.view.shape, c.rain, seed)
        rows, cols = np.nonzero(texture)   # by row
        # a streak's pixel in 5 bytes, not 24: the frame's tables leave the caches between frames
        self._streaks = ((rows * g.view.shape[1] + cols).astype(np.uint32), texture[rows, cols],
                         np.searchsorted(rows, np.arange(max(1, texture.shape[0]) + 1)), STREAK_RGB,
                         np.arange(256) / 255.0, bool(len(self._border)))
        self._frames = 0
        self._tables = self._groups()

    def _statics(self) -> None:
        """Per pixel, as bytes: the ground's fog transmittance (x 255), the headlights on the ground and the beams'
        cone (x LIT); the runs of pixels of ground (spans)."""
        c, g = self.condition, self.geometry
        w = g.view.shape[1]
        on = g.ground_mask
        lit = np.zeros(g.view.size, dtype=np.uint8)
        self._cone = np.zeros(g.view.size, dtype=np.uint8)
        if c.night >= 0:
            beams(lit, self._cone, self._view, g.ground.reshape(-1), g.cams, self._beam, w)
        self._lit = lit
        # a ray's length (a metre along the view's axis is that far along the ray: 1 to 1.5 in these cameras) in
        # 128ths, a byte a pixel (at most 2: a camera wider than 90 degrees has its corners' fog a little thin)
        self._reach = np.round(np.minimum(g.lengths, 255.0 / 128.0) * 128.0).astype(np.uint8).reshape(-1)
        with np.errstate(invalid="ignore", over="ignore"):
            t = np.where(on, np.exp(-c.density * g.ground * g.lengths), 1.0)
        self._fog = np.round(t * 255.0).astype(np.uint8).reshape(-1)
        edges = np.flatnonzero(np.diff(np.r_[0, on.reshape(-1).astype(np.int8), 0]))
        self._spans = edges.reshape(-1, 2).astype(np.int64)

    def _ground_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Every view's rows of ground: (flat index of the first pixel, of the end) and the car-frame ground point
        [m] of the first pixel and its step a pixel (a row's ground points lie on a line)."""
        g, w = self.geometry, self.geometry.view.shape[1]
        rows, spots = [], []
        for v, p in enumerate(g.places):
            top, left, vh, vw = p.rect
            for r in range(top, top + vh):
                d = g.ground[r, left:left + 2]
                if np.isfinite(d).all():
                    a, b = (g.eyes[v, :2] + d[:, None] * g.rays[r, left:left + 2, :2]).astype(np.float64)
                    rows.append((r * w + left, r * w + left + vw))
                    spots.append((*a, *(b - a)))
        return np.array(rows, dtype=np.int64).reshape(-1, 2), np.array(spots, dtype=np.float64).reshape(-1, 4)

    def _wet_road(self) -> tuple[np.ndarray, np.ndarray]:
        """Per view, the row of the ground at each distance along its axis (STEP a metre; the lowest row's below
        its distance, -1 in a view without ground), and per view and row how much a wet road mirrors there: more at
        grazing angles, far away; a dry road: one entry of each."""
        g = self.geometry
        if self.condition.wetness <= 0:
            return np.full((len(g.places), 1), -1, dtype=np.int64), np.zeros((len(g.places), 1), dtype=np.float32)
        contact = np.full((len(g.places), int(400 * STEP) + 1), -1, dtype=np.int64)
        for v, p in enumerate(g.places):
            top, left, vh, vw = p.rect
            near = g.ground[top:top + vh, left + vw // 2]
            for r in np.flatnonzero(np.isfinite(near)):   # the ground's distance falls row by row down the view
                contact[v, :min(int(round(near[r] * STEP)), contact.shape[1] - 1) + 1] = top + r
        wetness = np.zeros((len(g.places), g.view.shape[0]), dtype=np.float32)
        for v, p in enumerate(g.places):
            top, left, vh, vw = p.rect
            d = g.ground[top:top + vh, left + vw // 2]
            far = np.minimum(1.0, np.where(np.isfinite(d), d, 0.0) / 60.0)
            wetness[v, top:top + vh] = np.where(np.isfinite(d), self.condition.wetness * (0.35 + 0.65 * far), 0.0)
        return contact, wetness

    def _groups(self) -> tuple:
        """What light_kernels.draw reads besides the frame, grouped as it takes them."""
        c, g = self.condition, self.geometry
        lamps = self.lamps or Lamps(np.zeros((0, 2)), np.zeros((0, 2)), 0.0)
        lights = self.car_lights or CarLights(np.zeros((1, 2, 3)), np.zeros((1, 2, 3)), 0.0)
        return (g.view, g.cams, bool(c.shades),
                (self._spans, *self._ground_bytes(), self._gain, self._dark, self._fog_rgb),
                (self._reach, self._cone, self._fall, self._fog_table, self._lamp_rgb, float(self._lamp_reach),
                 self._contact, self._wetness, self._road, float(MIRRORED * g.cams[0, 13]), row_view(g.view),
                 float(self._beam[2]), self._near, view_segments(g.view), bool((g.view == 0).all())),
                (np.asarray(lamps.pools, dtype=np.float64).reshape(-1, 2),
                 np.asarray(lamps.heads, dtype=np.float64).reshape(-1, 2), float(lamps.height), self._lamp_glow,
                 self._rows, self._spots),
                (np.asarray(lights.tails, dtype=np.float64), np.asarray(lights.heads, dtype=np.float64), TAIL_RGB,
                 HEAD_RGB, float(lights.strength), float(self._density), float(self._streak)),
                (np.asarray(self._sun, dtype=np.float64), self._sprite), self._streaks)

    def _ground_bytes(self) -> tuple[np.ndarray, np.ndarray]:
        """The ground's fog and headlights bytes as ground (sim/render/effect_kernels.py) reads them: none of one
        that changes nothing (no fog: every byte 255; no headlights: every byte 0), the other kept."""
        none = np.zeros(0, dtype=np.uint8)
        fogged, lit = bool((self._fog != 255).any()), bool(self._lit.any())
        return self._fog if fogged or not lit else none, self._lit if lit or not fogged else none

    @property
    def needs_depth(self) -> bool:
        """Whether apply reads the renderer's depth: for what the distance changes, and for the lights (hidden
        behind what stands in front of them)."""
        return self.condition.shades or self.car_lights is not None or self.lamps is not None

    def apply(self, frame: np.ndarray, depth: np.ndarray | None, x: float, y: float, yaw: float,
              cars: tuple | None = None) -> np.ndarray:
        """The frame with the condition drawn over it (a new array) seen from a car at (x, y) [m] with yaw [rad]:
        depth (h, w) float32, the objects' distances along each view's axis [m] (inf where none; the insets'
        borders are set to inf here; None where not needs_depth); cars: (x, y, yaw, model) arrays of the other
        cars. One compiled call (light_kernels.draw) draws it all."""
        out = frame.copy() if depth is None else np.empty_like(frame)
        if depth is not None and len(self._border):
            depth.reshape(-1)[self._border] = np.inf
        draw(out, np.ascontiguousarray(frame), NO_DEPTH if depth is None else depth, float(x), float(y), float(yaw),
             self._frames, NO_CARS if cars is None or self.car_lights is None else cars, *self._tables)
        self._frames += 1
        return out


def row_view(view: np.ndarray) -> np.ndarray:
    """Per row of view (h, w), the one view its pixels show (the insets' borders aside), -1 where several or none."""
    shown = np.where(view >= 0, view, view.max(axis=1, keepdims=True)).astype(np.int64)
    return np.where((shown == shown[:, :1]).all(axis=1) & (view.max(axis=1) >= 0), shown[:, 0], -1)


def view_segments(view: np.ndarray) -> np.ndarray:
    """The runs of each row's pixels of one view of view (h, w) (the insets' borders left out), row by row, left to
    right: (n, 4) int64, the flat index of the first pixel and of the end, the view, the row."""
    w = view.shape[1]
    out = []
    for r, row in enumerate(view.astype(np.int64)):
        edges = np.flatnonzero(np.diff(np.r_[-2, row, -2]))   # where a run starts, then where the last ends
        out += [(r * w + a, r * w + b, row[a], r) for a, b in zip(edges[:-1], edges[1:]) if row[a] >= 0]
    return np.array(out, dtype=np.int64).reshape(-1, 4)


def mirrored_depths(contact: np.ndarray, height: int, tall: float) -> np.ndarray:
    """Per view and row of a frame `height` rows tall, the distances [m] (lo, hi) outside which a wet road mirrors
    no object pixel of the row ((0, 0): none), from the ground's rows at each distance (contact, as Effects has it)
    and `tall` (sim/render/effect_kernels.py _by_day): a pixel at d in [k, k + 1) / STEP (the last entry: all beyond)
    is mirrored to row 2 g - r (g = contact[v, k]) only if g >= 0, r < 2 g - r < height and (g - r) k / STEP <=
    tall, (g - r) d being at least that."""
    out = np.zeros((contact.shape[0], height, 2))
    if contact.shape[1] == 1:   # a dry road
        return out
    k = np.arange(contact.shape[1])
    for v, g in enumerate(contact):
        for r in range(height):
            can = (g >= 0) & (g > r) & (2 * g - r < height) & ((g - r) * (k / STEP) <= tall)
            if can.any():
                lo, hi = k[can].min(), k[can].max()
                out[v, r] = lo / STEP, np.inf if hi == len(g) - 1 else (hi + 1) / STEP
    return out


def glare_sprite(strength: float, focal: float) -> np.ndarray:
    """How far each pixel around the sun goes to white (2 k + 1 square, k where the glare falls under a level), for
    a camera of focal length `focal` [px]: the sun's disc white, its glare exp(-(1 - cos angle) / GLARE_WIDTH)."""
    reach = GLARE_WIDTH * math.log(strength * 255.0)   # 1 - cos where it falls under a level
    k = int(math.ceil(math.tan(math.acos(1.0 - reach)) * focal))
    dy, dx = np.mgrid[-k:k + 1, -k:k + 1]
    off = 1.0 - np.cos(np.arctan(np.hypot(dx, dy) / focal))
    sprite = np.where(off < SUN_DISC, 1.0, strength * np.exp(-off / GLARE_WIDTH))
    return np.where(sprite * 255.0 < 1.0, 0.0, sprite).astype(np.float32)


def rain_streaks(shape: tuple[int, int], density: float, seed: int) -> np.ndarray:
    """The rain's streaks (2 h, w) uint8 alpha: slanted, anti-aliased lines, read a frame's height at a time from
    a row that moves down every frame, seamless across the wrap; (0, w) without rain."""
    h, w = shape
    if density <= 0:
        return np.zeros((0, w), dtype=np.uint8)
    rng = np.random.default_rng([int(seed), 0x4A1])
    rows = 2 * h
    out = np.zeros((rows + h, w), dtype=np.uint8)
    slant = rng.uniform(-0.25, 0.25)
    for _ in range(int(density * rows * w / 1000)):
        x, y = rng.uniform(0, w), rng.uniform(0, rows)
        length = rng.uniform(0.04, 0.12) * h
        alpha = int(rng.uniform(40, 110))
        p0 = (int(x * 16), int(y * 16))
        p1 = (int((x + slant * length) * 16), int((y + length) * 16))
        cv2.line(out, p0, p1, alpha, 1, cv2.LINE_AA, 4)
    out[:h] = np.maximum(out[:h], out[rows:])   # what ran past the bottom comes back at the top
    return np.ascontiguousarray(out[:rows])

