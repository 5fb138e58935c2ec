"""drive --view and serve --view: a running job's loop published to the studio's page, as a step callback of
drivestudio/loop.py's run_loop. Read-only by default; with --view ...,control the page holding the wheel may pause,
resume and single-step the run (a paused lock-step run keeps its driver waiting). Its cost to the loop is a flag
test per step, and a snapshot of references when a page is ready for a frame (at most --view's fps a second); the
drawing and encoding run in the server's threads (docs/benchmarks.md measures the slowdown).
"""
from __future__ import annotations

import sys

from drivestudio.loop import StepRecord
from drivestudio.studio.controls import Controls
from drivestudio.studio.protocol import Message
from drivestudio.studio.publisher import Publisher
from drivestudio.studio.server import Server, new_token
from drivestudio.studio.watch import Watch


class RunView:
    def __init__(self, run, world, metrics):
        """`run`: drivestudio/drive_session.py's Run, with its View."""
        view = run.view
        self.label = label = run.label
        self.controls = Controls(realtime=run.realtime) if view.control else None
        kit = run.plugin.studio()
        self.watch = Watch(Publisher(view.fps), kit.view_for(world, run.config), metrics)
        self.extra = {"driver": label, "human": False, "takeover": False, "recording": None,
                      "realtime": run.realtime, "scene": kit.scene(run.config)}
        decl = world.declaration
        hello = {"world": decl.name, "title": decl.title, "dt": decl.dt, "studio": False,
                 "controls": view.control, "cameras": [c.name for c in decl.cameras],
                 "action": [{"name": a.name, "low": a.low, "high": a.high, "neutral": a.neutral}
                            for a in decl.action],
                 "drivers": [label], "modes": [], "operations": [], "scene_key": kit.scene_key,
                 "scenes": [], "labels_note": kit.note}
        host = view.host or "127.0.0.1"
        self.server = Server(view.socket, self.watch.publisher, hello=lambda client: hello,
                             handle=self._handle, leave=self._left, token=new_token() if view.host else None,
                             drives=False, controls=view.control)
        self.server.start()
        print(f"watch the run at {self.server.url(host)}", file=sys.stderr, flush=True)
        if Server.where(host):
            print(Server.where(host), file=sys.stderr, flush=True)

    def _handle(self, msg, client) -> str | None:
        if self.controls is None:   # the server lets nothing through without --view ...,control; kept for safety
            return "this run is only watched here"
        self.controls.put(msg)
        return None

    def _left(self, client) -> None:
        if self.controls is not None:    # nobody may be left to resume a paused run
            self.controls.put(Message("resume"))

    def __call__(self, rec: StepRecord) -> None:
        paused = self.controls is not None and self.controls.paused
        self.watch.step(rec, None, None, {**self.extra, "paused": paused}, self.label)
        if self.controls is not None and self.controls.hold(lambda msg: None, idle=self._idle):
            self.watch.rate.restart()     # a pause is not the loop falling behind

    def _idle(self) -> None:
        assert self.controls is not None
        if self.watch.republish(None, None, {**self.extra, "paused": self.controls.paused}, self.label,
                                self.controls.changed):
            self.controls.changed = False

    def close(self) -> None:
        self.server.stop("the run ended")
