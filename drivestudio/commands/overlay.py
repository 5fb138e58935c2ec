"""drivestudio overlay --data DIR --model CKPT|oracle --out DIR: truth beside estimate for chosen samples (PNG or
a video). The highway draws DeepDriving's top-down box overlays; every world draws its own (worlds' plugins)."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from core.files import check_output, check_output_dir
from drivestudio import worlds
from drivestudio.checkpoints import check_device, load_predictor_for
from drivestudio.commands.common import add_device_option
from drivestudio.commands.numbers import count, seed
from drivestudio.errors import UsageError
from drivestudio.outputs import VideoWriter, write_png

if TYPE_CHECKING:
    from perception.datasets import FrameDataset
    from perception.predictor import Predictor

# one chosen sample: its images at the step, its record, {output: estimate} (None: the oracle draws the truth alone)
Item = tuple[tuple, dict, dict | None]


def register(sub) -> None:
    p = sub.add_parser("overlay", help="draw ground truth and estimate side by side (highway: top-down box "
                                       "overlays), as PNGs or an MP4",
                       description="For each chosen sample: the camera frame(s) beside the world's view of truth and "
                                   "estimate. The highway: a top-down view of the lanes, the truth as filled boxes "
                                   "(host red, cars yellow) and the estimate as outlines (host green, cars purple), "
                                   "with an error bar per indicator.")
    p.add_argument("--data", required=True, help="dataset folder")
    p.add_argument("--model", default="oracle", help="a checkpoint of the dataset's world, or 'oracle' to draw the "
                                                     "truth alone")
    p.add_argument("--out", help="folder for the PNGs (required without --video)")
    p.add_argument("--split", choices=("train", "val", "test", "all"), default="test", help="(default test)")
    p.add_argument("--select", choices=("first", "random", "worst"), default="first",
                   help="first N samples, a random sample, or the N worst by error (default first)")
    p.add_argument("-n", type=count(1, 10**6), help="how many samples (default 20; with --video the whole "
                                                           "episode)")
    p.add_argument("--seed", type=seed(), default=0, help="seed of --select random")
    p.add_argument("--video", help="write consecutive overlays of one episode as this .mp4 instead")
    p.add_argument("--episode", type=count(0, 10**9), help="the episode for --video (default: the "
                                                                        "split's first)")
    add_device_option(p)
    p.set_defaults(func=run)


def check_combination(args) -> None:
    """Options that would be ignored with the others given are refused (a given option is never dropped)."""
    if args.video and args.out:
        raise UsageError("--out FOLDER (PNGs) and --video FILE.mp4 (one episode as a video) are alternatives: "
                         "give one")
    if args.video and args.select != "first":
        raise UsageError("--select goes with PNGs (--out); --video draws one episode in order")
    if not args.video and args.episode is not None:
        raise UsageError("--episode goes with --video")
    if args.select != "random" and args.seed != 0:
        raise UsageError("--seed goes with --select random")


def run(args) -> int:
    # lazy: perception's readers import torch and pyarrow (seconds); only drawing overlays needs them
    from perception.datasets import FrameDataset
    from perception.shards import Dataset, DatasetError  # lazy: pyarrow

    check_device(args.device)
    check_combination(args)
    if args.video:
        check_output(args.video, (".mp4",), "video")
    elif not args.out:
        raise UsageError("give --out FOLDER for PNG overlays, or --video FILE.mp4")
    else:
        check_output_dir(args.out)
    if args.n is None and not args.video:
        args.n = 20
    split = None if args.split == "all" else args.split
    predictor = None
    if args.model != "oracle":
        predictor = load_predictor_for(args.model, Dataset(Path(args.data)).world, args.device)
    try:
        ds = FrameDataset(args.data, split, targets=None if predictor is None else predictor.labels,
                          normalised=False)
    except DatasetError as e:
        raise UsageError(str(e)) from None
    plugin = worlds.get(ds.data.world)
    label = "oracle" if predictor is None else predictor.name

    items = _estimate(ds, _choose(args, ds), predictor)
    if args.select == "worst" and not args.video:
        items.sort(key=lambda it: -plugin.overlay_error(it[1], it[2]))
        items = items[:args.n]

    writer = VideoWriter(args.video) if args.video else None
    try:
        for images, record, est in items:
            img = plugin.overlay(images, record, est, label)
            if writer is not None:
                writer.write(img)
            else:
                write_png(Path(args.out) / f"overlay-ep{record['episode']:04d}-{record['step']:04d}.png", img)
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    if writer is not None:
        writer.close()
        print(f"wrote {writer.frames} overlays to {args.video}")
    else:
        print(f"wrote {len(items)} overlays to {args.out}/")
    return 0


def _choose(args, ds: FrameDataset) -> list[int]:
    """The samples to draw: one episode's (--video), a random, the first or (ranked later) every sample."""
    if args.video:
        episodes = {s.episode: k for k, s in enumerate(ds.shards)}
        ep = args.episode if args.episode is not None else ds.shards[0].episode
        if ep not in episodes:
            raise UsageError(f"episode {ep} is not in split '{args.split}' (episodes: "
                             f"{', '.join(str(e) for e in sorted(episodes))})")
        wanted = [i for i in range(len(ds)) if ds.locate(i)[0] == episodes[ep]]
        return wanted if args.n is None else wanted[:args.n]
    if args.select == "random":
        rng = np.random.default_rng(args.seed)
        return sorted(rng.choice(len(ds), min(args.n, len(ds)), replace=False).tolist())
    if args.select == "first":
        return list(range(min(args.n, len(ds))))
    return list(range(len(ds)))  # ranked by the caller, once every sample is estimated


def _estimate(ds: FrameDataset, wanted: list[int], predictor: Predictor | None) -> list[Item]:
    """Each wanted sample with the model's estimate, in batches of 32."""
    from tqdm import tqdm  # lazy: 20 ms that `drivestudio --help` need not pay

    items: list[Item] = []
    batch: list[int] = []
    for i in tqdm(wanted, desc="estimating", unit="sample", disable=len(wanted) < 200, file=sys.stderr,
                  mininterval=1.0 if sys.stderr.isatty() else 30.0):
        batch.append(i)
        if len(batch) == 32:
            items += _estimate_batch(ds, batch, predictor)
            batch = []
    return items + _estimate_batch(ds, batch, predictor)


def _estimate_batch(ds: FrameDataset, batch: list[int], predictor: Predictor | None) -> list[Item]:
    if not batch:
        return []
    est = None
    if predictor is not None:
        est = predictor.batch([ds.images(*ds.locate(i)) for i in batch],
                              [m if m >= 0 else None for m in (ds.mode_of(i) for i in batch)]
                              if predictor.modes else None)
    items: list[Item] = []
    for k, i in enumerate(batch):
        images, record = ds.record(i)
        record["targets"] = dict(zip(ds.outputs, ds.raw_targets(i).tolist()))   # the sample's true outputs
        items.append((images, record, None if predictor is None or est is None
                      else dict(zip(predictor.outputs, est[k]))))
    return items
