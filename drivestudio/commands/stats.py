"""drivestudio stats DIR: what a dataset covers, as a table, a JSON file and per-label histograms."""
from __future__ import annotations

from pathlib import Path

from core.files import check_output_dir
from drivestudio import worlds
from drivestudio.outputs import write_json, write_text


def register(sub) -> None:
    p = sub.add_parser("stats", help="summarise a dataset's coverage and plot per-label histograms",
                       description="Frames per split (and how the split was made), and what the data covers: for the "
                                   "highway the in-lane / on-marking / overlap shares, frames per lane position, near "
                                   "cars, angle spread and lane changes; for any world the spread of every label, the "
                                   "balance of behavioural modes and the share of every flag (collisions, "
                                   "corrections). Histograms as PNG. Reads labels only.")
    p.add_argument("data", help="dataset folder")
    p.add_argument("--split", choices=("train", "val", "test", "all"), default="all")
    p.add_argument("--out", help="folder for stats.json and the histograms (default DATA/stats)")
    p.add_argument("--fingerprint", action="store_true",
                   help="also the content fingerprint: SHA-256 of the labels and of the decoded frames, equal for the "
                        "same data however its files were written (to compare two runs, two machines); decodes the "
                        "frames the frame cache does not hold, about a millisecond each")
    p.set_defaults(func=run)


def run(args) -> int:
    from perception.shards import Dataset  # lazy: pyarrow (80 ms) loads only when a dataset is read

    ds = Dataset(Path(args.data))
    out = check_output_dir(Path(args.out) if args.out else Path(args.data) / "stats")
    coverage = worlds.get(ds.world).coverage()
    summary, values = coverage.summarize(ds, None if args.split == "all" else args.split)
    if args.fingerprint:
        from perception.fingerprint import dataset_fingerprint  # decodes frames: only when asked
        summary["fingerprint"] = dataset_fingerprint(ds, None if args.split == "all" else args.split)
    text = coverage.table(summary)
    if args.fingerprint:
        fp = summary["fingerprint"]
        text += f"\n\nfingerprint of {fp['frames']} frames: labels {fp['labels']}, images {fp['images']}"
    write_json(out / "stats.json", summary)
    write_text(out / "stats.md", text + "\n")
    pngs = coverage.histograms(values, out, ds.declaration)
    print(text)
    print(f"\nwrote {out / 'stats.json'} and {len(pngs)} histogram PNGs in {out}/")
    return 0
