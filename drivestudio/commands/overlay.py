"""drivestudio overlay --data DIR --model CKPT|oracle --out DIR: box overlays of chosen frames (or a video)."""
from __future__ import annotations

import sys
from pathlib import Path

from ..errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("overlay", help="draw ground truth and estimate as top-down box overlays (PNG or MP4)",
                       description="For each chosen frame: the camera frame beside a top-down view of the lanes, "
                                   "the truth as filled boxes (host red, cars yellow) and the estimate as "
                                   "outlines (host green, cars purple), with an error bar per indicator.")
    p.add_argument("--data", required=True, help="dataset folder")
    p.add_argument("--model", default="oracle", help="a checkpoint, or 'oracle' to draw the truth alone")
    p.add_argument("--out", required=True, help="folder for the PNGs")
    p.add_argument("--split", choices=("train", "val", "test", "all"), default="test", help="(default test)")
    p.add_argument("--select", choices=("first", "random", "worst"), default="first",
                   help="first N frames, a random sample, or the N worst by error (default first)")
    p.add_argument("-n", type=int, help="how many frames (default 20; with --video the whole episode)")
    p.add_argument("--seed", type=int, default=0, help="seed of --select random")
    p.add_argument("--video", help="write consecutive overlays of one episode as this .mp4 instead")
    p.add_argument("--episode", type=int, help="the episode for --video (default: the split's first)")
    p.add_argument("--device", default="cpu")
    p.set_defaults(func=run)


def _predict(predictor, images):
    """(estimates (B, 14) in canonical order, lanes_left (B,) or None) of a batch of frames, one forward pass."""
    import numpy as np

    from shm_bridge.vocabulary import INDEX, INDICATORS
    outputs = predictor.outputs(images)
    est = np.zeros((len(images), len(INDICATORS)))
    for i, name in enumerate(predictor.labels):
        if name in INDEX:
            est[:, INDEX[name]] = outputs[:, i]
    lanes_left = outputs[:, predictor.labels.index("lanes_left")] if "lanes_left" in predictor.labels else None
    return est, lanes_left


def run(args) -> int:
    import numpy as np
    from tqdm import tqdm

    from perception.overlay import mean_normalised_error
    from perception.shards import Dataset
    from shm_bridge.vocabulary import INDICATORS

    from ..outputs import VideoWriter, write_png
    from ..overlays import overlay_record
    from .common import load_perception

    if args.n is not None and args.n < 1:
        raise UsageError("-n must be at least 1")
    if args.n is None and not args.video:
        args.n = 20
    ds = Dataset(Path(args.data))
    shards = ds.select(None if args.split == "all" else args.split)
    if not shards:
        raise UsageError(f"the dataset has no frames in split '{args.split}'")
    predictor = load_perception(args.model, args.device)
    label = "oracle" if predictor is None else predictor.name

    if args.video:
        episodes = {s.episode: s for s in shards}
        ep = args.episode if args.episode is not None else shards[0].episode
        if ep not in episodes:
            raise UsageError(f"episode {ep} is not in split '{args.split}' (episodes: "
                             f"{', '.join(str(e) for e in sorted(episodes))})")
        count = episodes[ep].frames if args.n is None else min(args.n, episodes[ep].frames)
        wanted = [(episodes[ep], i) for i in range(count)]
    else:
        index = [(s, i) for s in shards for i in range(s.frames)]
        if args.select == "random":
            rng = np.random.default_rng(args.seed)
            wanted = [index[i] for i in sorted(rng.choice(len(index), min(args.n, len(index)), replace=False))]
        elif args.select == "first":
            wanted = index[:args.n]
        else:
            wanted = index  # ranked below, once every frame is estimated

    readers = {}

    def load(item):
        shard, row = item
        if shard.file not in readers:
            readers[shard.file] = ds.reader(shard)
        image, record = readers[shard.file].row(row)
        truth = np.array([record[n] for n in INDICATORS], dtype=np.float64)
        return image, record, truth

    items = []  # (record, image, truth, estimate, lanes_left)
    batch = []

    def flush():
        if not batch:
            return
        if predictor is None:
            est, ll = [truth for _, _, truth in batch], None
        else:
            est, ll = _predict(predictor, [image for image, _, _ in batch])
        for k, (image, record, truth) in enumerate(batch):
            items.append((record, image, truth, np.asarray(est[k]), None if ll is None else float(ll[k])))
        batch.clear()

    for item in tqdm(wanted, desc="estimating", unit="frame", disable=len(wanted) < 200, file=sys.stderr,
                     mininterval=1.0 if sys.stderr.isatty() else 30.0):
        batch.append(load(item))
        if len(batch) == 32:
            flush()
    flush()
    if args.select == "worst" and not args.video:
        items.sort(key=lambda it: -mean_normalised_error(it[2], it[3]))
        items = items[:args.n]

    out = Path(args.out)
    writer = VideoWriter(args.video) if args.video else None
    try:
        for record, image, truth, est, ll in items:
            title = f"episode {record['episode']} frame {record['step']}  {record['track']}, {record['lanes']} lanes"
            img = overlay_record(image, record, truth, None if predictor is None else est, title, ll, label)
            if writer is not None:
                writer.write(img)
            else:
                write_png(out / f"overlay-ep{record['episode']:04d}-{record['step']:04d}.png", img)
    except BaseException:
        if writer is not None:
            writer.abort()
        raise
    if writer is not None:
        writer.close()
        print(f"wrote {writer.frames} overlays to {args.video}")
    else:
        print(f"wrote {len(items)} overlays to {out}/")
    return 0
