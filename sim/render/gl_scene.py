"""A scene in OpenGL: its geometry uploaded once, drawn view by view into one frame and read back.

The geometry comes in groups (a world's chunks of road: their ground and static objects as triangles, the ground's
outlines as lines; one range of vertices each, drawn when the group is in view) and models (cars: drawn as
instances, one per car in view). A view is two indirect draw calls, its triangles and its lines. The frame starts as
a fixed base image (the backdrops and the insets' borders); an inset is drawn first and then kept (its depth set
nearest) while the views after it are drawn.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.render.gl_context import gl_context
from sim.render.gl_geometry import VERTEX_ATTRIBUTES, VERTEX_FORMAT, WIDTH
from sim.render.gl_programs import FRAGMENT, OBJECT_DEPTH, VERTEX
from sim.render.gl_views import View

INSTANCE_FORMAT = "2f 2f 3f/i"
INSTANCE_ATTRIBUTES = ("in_place", "in_heading", "in_paint")
STILL = np.array([[0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]], dtype=np.float32)   # instance 0: the static scenery
COMMAND = 5   # uint32 fields of an indirect draw command (below)
CLIP_DISTANCE0 = 0x3000   # GL_CLIP_DISTANCE0: the objects' far plane (sim/render/gl_programs.py)


@dataclass
class Group:
    """What a group (a chunk) draws: vertex rows of its triangles and of its lines (sim/render/gl_geometry.py)."""

    triangles: np.ndarray
    lines: np.ndarray


class GLScene:
    def __init__(self, groups: list[Group], models: list[np.ndarray], base: np.ndarray, light, ambient: float,
                 diffuse: float):
        """models: vertex rows of each model's triangles; base: the frame (h, w, 3) uint8 before any view; light:
        unit vector towards the light; ambient, diffuse: its coefficients (TinyRenderer's)."""
        self._ctx = ctx = gl_context()
        with ctx:
            self._build(ctx, groups, models, base, light, ambient, diffuse)

    def _build(self, ctx, groups: list[Group], models: list[np.ndarray], base: np.ndarray, light, ambient: float,
               diffuse: float) -> None:
        parts = [g.triangles for g in groups] + list(models) + [g.lines for g in groups]
        firsts = np.concatenate([[0], np.cumsum([len(p) for p in parts])]).astype(np.int64)
        n, k = len(groups), len(models)
        self._triangles = (firsts[:n], firsts[1:n + 1])              # each group's first vertex and end
        self._models = (firsts[n:n + k], firsts[n + 1:n + k + 1] - firsts[n:n + k])   # first vertex, count
        self._lines = (firsts[n + k:2 * n + k], firsts[n + k + 1:])
        rows = np.concatenate(parts) if parts else np.zeros((0, WIDTH), np.float32)
        self._vertices = ctx.buffer(np.ascontiguousarray(rows, dtype=np.float32).tobytes() or bytes(4 * WIDTH))
        self._instances = ctx.buffer(reserve=4 * 7 * 64, dynamic=True)
        self._commands = ctx.buffer(reserve=4 * COMMAND * 64, dynamic=True)
        self._program = ctx.program(vertex_shader=VERTEX, fragment_shader=FRAGMENT)
        self._program["light"].value = tuple(float(v) for v in light)
        self._program["ambient"].value = float(ambient)
        self._program["diffuse"].value = float(diffuse)
        self._vao = ctx.vertex_array(self._program, [(self._vertices, VERTEX_FORMAT, *VERTEX_ATTRIBUTES),
                                                     (self._instances, INSTANCE_FORMAT, *INSTANCE_ATTRIBUTES)])
        h, w = base.shape[:2]
        self.size = (h, w)
        self._base = ctx.texture((w, h), 3, np.ascontiguousarray(base, dtype=np.uint8).tobytes())
        self._base_fbo = ctx.framebuffer(color_attachments=[self._base])
        self._colour = ctx.renderbuffer((w, h), 4)
        self._depth = ctx.depth_renderbuffer((w, h))
        self._fbo = ctx.framebuffer(color_attachments=[self._colour], depth_attachment=self._depth)

    @staticmethod
    def _runs(on: np.ndarray, first: np.ndarray, end: np.ndarray) -> list[tuple[int, int]]:
        """(first vertex, count) of each run of consecutive groups `on` (indices, ascending) with vertices."""
        out = []
        if len(on):
            for run in np.split(on, np.flatnonzero(np.diff(on) != 1) + 1):
                a, b = int(first[run[0]]), int(end[run[-1]])
                if b > a:
                    out.append((a, b - a))
        return out

    def _commands_of(self, views: list[View]) -> tuple[np.ndarray, np.ndarray, list[tuple[int, int, int]]]:
        """The instances of all views, the indirect draw commands (count, instances, first vertex, first instance,
        0) and each view's (first command, triangle commands, line commands). moderngl reads the commands 20 bytes
        apart, the size of an indexed draw's, for arrays as well: hence the fifth, unused field."""
        instances, spans = [STILL], []
        commands: list[tuple[int, int, int, int, int]] = []
        n_inst = 1
        for v in views:
            start = len(commands)
            on = np.flatnonzero(v.groups)
            commands += [(count, 1, first, 0, 0) for first, count in self._runs(on, *self._triangles)]
            for m, cars in enumerate(v.cars):
                if len(cars):
                    commands.append((int(self._models[1][m]), len(cars), int(self._models[0][m]), n_inst, 0))
                    instances.append(np.asarray(cars, dtype=np.float32))
                    n_inst += len(cars)
            n_tri = len(commands) - start
            commands += [(count, 1, first, 0, 0) for first, count in self._runs(on, *self._lines)]
            spans.append((start, n_tri, len(commands) - start - n_tri))
        return np.concatenate(instances), np.asarray(commands, dtype=np.uint32).reshape(-1, COMMAND), spans

    def render(self, views: list[View], depth: np.ndarray | None = None) -> np.ndarray:
        """The frame with `views` drawn in order, (h, w, 3) uint8 RGB; `depth` (h, w) float32, when given, gets the
        objects' distances along each view's axis [m] (inf where none)."""
        # current only while drawing, then the one before again: another EGL context of this process (PyBullet's
        # EGL plugin) may be made current between frames
        with self._ctx:
            return self._render(views, depth)

    def _render(self, views: list[View], depth: np.ndarray | None = None) -> np.ndarray:
        ctx, fbo, prog = self._ctx, self._fbo, self._program
        instances, commands, spans = self._commands_of(views)
        for buf, data in ((self._instances, instances), (self._commands, commands)):
            if data.nbytes > buf.size:
                buf.orphan(2 * data.nbytes)
            buf.write(data.tobytes())
        if depth is not None:
            depth[:] = np.inf
        ctx.copy_framebuffer(fbo, self._base_fbo)
        fbo.use()
        h, w = self.size
        self._clear_depth(1.0, (0, 0, w, h))
        ctx.enable_only(ctx.DEPTH_TEST | ctx.CULL_FACE)
        ctx.enable_direct(CLIP_DISTANCE0)
        for v, (first, n_tri, n_lines) in zip(views, spans):
            top, left, vh, vw = v.rect
            fbo.viewport = (left, top, vw, vh)   # the frame's rows are OpenGL's rows: y counts down the frame
            fbo.scissor = (left, top, vw, vh)
            prog["view_projection"].write(np.ascontiguousarray(v.matrix.T, dtype=np.float32).tobytes())
            prog["ground_shift"].value = v.ground_shift
            prog["object_shift"].value = v.object_shift
            ctx.front_face = "cw" if v.clockwise else "ccw"
            if n_tri:
                self._vao.render_indirect(self._commands, mode=ctx.TRIANGLES, count=n_tri, first=first)
            if n_lines:
                self._vao.render_indirect(self._commands, mode=ctx.LINES, count=n_lines, first=first + n_tri)
            if depth is not None:   # before a kept view's depth is cleared
                self._read_depth(depth, v)
            if v.keep is not None:
                kt, kl, kh, kw = v.keep
                self._clear_depth(0.0, (kl, kt, kw, kh))
        fbo.scissor = None
        out = np.empty((h, w, 3), dtype=np.uint8)
        fbo.read_into(out, components=3)
        return out

    def _read_depth(self, depth: np.ndarray, v: View) -> None:
        """A view's objects' distances [m] into its rectangle of `depth`, where later views do not draw: an object's
        window depth is (z' + 1) / 2 of its squeezed NDC depth z' = a z + b (gl_programs.OBJECT_DEPTH), every
        ground's lies beyond them all."""
        top, left, vh, vw = v.rect
        window = np.frombuffer(self._fbo.read(viewport=(left, top, vw, vh), components=1, attachment=-1, dtype="f4"),
                               dtype=np.float32).reshape(vh, vw)
        a, b = OBJECT_DEPTH
        z = ((2.0 * window - 1.0) - b) / a
        n, f = v.clip
        with np.errstate(divide="ignore"):
            metres = np.where(window < (a + b + 1.0) / 2 + 1e-4, 2 * f * n / ((f + n) - z * (f - n)), np.inf)
        area = depth[top:top + vh, left:left + vw]
        if v.keep is None:   # a later view: the insets' rectangles, kept at depth 0, hold their own distances
            metres = np.where(window == 0.0, area, metres)
        area[:] = metres

    def _clear_depth(self, depth: float, box: tuple[int, int, int, int]) -> None:
        """Set the depth of a box (x, y, width, height) of the frame, its colour untouched."""
        fbo = self._fbo
        fbo.color_mask = (False, False, False, False)
        fbo.clear(depth=depth, viewport=box)
        fbo.color_mask = (True, True, True, True)
        fbo.use()   # moderngl applies a framebuffer's colour mask when it is bound

    def release(self) -> None:
        with self._ctx:
            self._release()

    def _release(self) -> None:
        for obj in (self._vao, self._program, self._vertices, self._instances, self._commands, self._fbo,
                    self._base_fbo, self._base, self._colour, self._depth):
            obj.release()
