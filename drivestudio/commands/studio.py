"""drivestudio studio: a live studio in the browser, for any world (docs/studio.md).

    studio [--world W ...] [--model M] [--checkpoint CKPT ...]       open the printed URL in a browser

The page shows the camera (the stereo pair on the sidewalk), the top-down view with truth and estimate, every
label's truth against the estimate with error bars, the controller's state and command, the run's metrics and the
loop rate. It pauses, steps, paces (real time or as fast as it can), switches the driver (the person at the
keyboard or gamepad, the world's own, any --checkpoint), the behavioural mode, and resets to a new seed, track or
path. One button records what is driven as a dataset (OUT/recordings/NAME). `drive ... --view` and
`serve ... --view` publish a running job to the same page.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from core.signals import Terminated, exit_on_sigterm
from drivestudio.checkpoints import check_checkpoint_path, check_device
from drivestudio.commands.common import add_device_option, add_world_options, plugin_for, run_dir, world_config
from drivestudio.commands.numbers import count, positive
from drivestudio.errors import UsageError

LOCALHOST = "127.0.0.1"
DEFAULT_PORT = 8765
VIEW_FPS = 10.0           # frames a second a watched run publishes at most (docs/benchmarks.md: its cost)
STUDIO_FPS = 60.0         # frames a second the studio publishes at most: a display shows no more, and drawing more
                          # takes the cores from a loop running as fast as it can


def register(sub) -> None:
    p = sub.add_parser("studio", help="a live studio in the browser: watch, drive, take over, record",
                       description=__doc__.split("\n", 1)[1], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--model", default=None, help="who drives at the start: human (default), the world's own "
                                                 "(oracle, expert, poor) or a checkpoint file")
    p.add_argument("--checkpoint", action="append", default=[], metavar="CKPT",
                   help="a checkpoint file, or a folder of *.pt, the page offers as a driver (repeatable)")
    add_device_option(p)
    add_world_options(p, "drive")
    p.add_argument("--host", help=f"listen on this address (default {LOCALHOST}); then the page needs the token of "
                                  "the printed URL")
    p.add_argument("--port", type=count(0, 65535), default=DEFAULT_PORT,
                   help=f"port (default {DEFAULT_PORT}; 0: any free one)")
    p.add_argument("--fast", action="store_true", help="start as fast as it can (default: real time)")
    p.add_argument("--shard-steps", type=count(20, 100_000), default=300,
                   help="steps per episode (shard) of a recording (default 300)")
    p.add_argument("--out", help="the run's folder; recordings go to OUT/recordings/NAME (default runs/studio-TIME)")
    p.set_defaults(func=run)


def _checkpoints(args, plugin) -> dict[str, str]:
    """{name the page shows: file} of every --checkpoint (and --model when it is a file)."""
    files: list[Path] = []
    for given in args.checkpoint:
        path = Path(given)
        if path.is_dir():
            found = sorted(path.glob("*.pt"))
            if not found:
                raise UsageError(f"--checkpoint {given}: the folder holds no *.pt checkpoint")
            files += found
        elif path.is_file():
            files.append(path)
        else:
            raise UsageError(f"--checkpoint must be a checkpoint file or a folder of them; no such file or folder: "
                             f"{given}")
    model = None   # --model's checkpoint, with the estimate filters it names (CKPT@pass_memory=15)
    if args.model is not None and args.model != "human" and args.model not in plugin.expert_names:
        spec = plugin.parse_driver(args.model)
        model = check_checkpoint_path(spec.source, ("human",) + tuple(plugin.expert_names))
        files.append(model)
    out: dict[str, str] = {}
    for f in files:
        if out.get(f.name, str(f)) != str(f) and f != model:
            raise UsageError(f"two checkpoints are called {f.name} ({out[f.name]}, {f}): the page names them by "
                             "file name; rename one")
        out[f.name] = args.model if f == model else str(f)
    if model is not None:
        args.model = model.name
    return out


def need_aiohttp() -> None:
    try:
        import aiohttp  # noqa: F401 - only to know it is there
    except ImportError:
        raise UsageError("the studio needs aiohttp: pip install 'drivestudio[studio]'") from None


def run(args) -> int:
    need_aiohttp()
    from drivestudio.studio.controls import Controls  # lazy: the studio loads only when it runs
    from drivestudio.studio.publisher import Publisher  # lazy: pyarrow
    from drivestudio.studio.server import Server, bind, new_token  # lazy: aiohttp
    from drivestudio.studio.session import Session  # lazy: pyarrow
    from drivestudio.studio.watch import Watch  # lazy: pyarrow

    check_device(args.device)
    plugin = plugin_for(args)
    checkpoints = _checkpoints(args, plugin)
    sock = bind(args.host or LOCALHOST, args.port)     # a port in use: one line, before any work
    server = None
    try:
        out = run_dir(args.out, "studio")
        publisher = Publisher(STUDIO_FPS)
        controls = Controls(realtime=not args.fast)
        session = Session(plugin, world_config(plugin, args), out, checkpoints, Watch(publisher, None), controls,
                          shard_steps=args.shard_steps, model=args.model, device=args.device)
        with exit_on_sigterm():
            session.open()                                 # options that cannot build the world: one line
            server = Server(sock, publisher, hello=lambda client: session.hello(), handle=session.submit,
                            leave=session.wheel_left, token=new_token() if args.host else None, drives=True)
            session.tell = server.broadcast
            server.start()
            print(f"drivestudio studio ({plugin.name}): open {server.url(args.host or LOCALHOST)}", flush=True)
            if Server.where(args.host or LOCALHOST):
                print(Server.where(args.host or LOCALHOST), flush=True)
            print(f"recordings go to {out / 'recordings'}; Ctrl-C stops", flush=True)
            try:
                session.run()
            except (KeyboardInterrupt, Terminated):
                print("studio stopped", file=sys.stderr)
    finally:
        if server is not None:
            server.stop()
        else:
            sock.close()
    return 0


# --- drive --view and serve --view --------------------------------------------------------------------------------
def add_view_options(p) -> None:
    g = p.add_argument_group("watching the run in a browser (docs/studio.md)")
    g.add_argument("--view", nargs="?", const=str(DEFAULT_PORT), metavar="[HOST:]PORT[,control][,fps=F]",
                   help=f"publish the run to a web page and print its URL: on PORT (default {DEFAULT_PORT}; 0: any "
                        f"free one) of HOST (default {LOCALHOST}; another address needs the URL's token), read-only "
                        f"unless `control` (pause, resume, single-step), at most F frames a second (default "
                        f"{VIEW_FPS:g})")


def view_address(text: str) -> tuple[str | None, int, bool, float]:
    """(host or None, port, control, fps) of a --view value, or one line (UsageError)."""
    where, *extras = [part.strip() for part in text.split(",")]
    host, _, port_text = where.rpartition(":")
    control, fps = False, VIEW_FPS
    for extra in extras:
        if extra == "control":
            control = True
        elif extra.startswith("fps="):
            fps = _number(extra[4:], "fps", positive(240.0))
        else:
            raise UsageError(f"--view {text}: after the address come 'control' and 'fps=F', got {extra!r}")
    return host or None, _number(port_text, "port", count(0, 65535)), control, fps


def _number(text: str, what: str, parse):
    """`text` read by one of drivestudio/commands/numbers.py's types, its refusal as one line naming --view."""
    try:
        return parse(text)
    except argparse.ArgumentTypeError as e:
        raise UsageError(f"--view: {what} {e}") from None


def bind_view(args):
    """Before any work: the --view port bound (one line and exit status 2 when it is in use), as the run's View;
    None without --view."""
    if args.view is None:
        return None
    host, port, control, fps = view_address(args.view)
    need_aiohttp()
    from drivestudio.drive_session import View  # lazy: the bridge, only when a run is watched
    from drivestudio.studio.server import bind  # lazy: aiohttp
    return View(bind(host or LOCALHOST, port), host, control, fps)
