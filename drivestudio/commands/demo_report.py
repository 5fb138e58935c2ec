"""The demo's REPORT.md: the two headline tables, and every picture the demo made shown where the report discusses
it (frames, curves, histograms, overlays), each video by a still of its middle frame beside its link. Plain Markdown
with paths relative to the report, so the folder reads offline in any Markdown viewer, moved or copied whole."""
from __future__ import annotations

import json
from pathlib import Path

import cv2

from drivestudio.outputs import write_png, write_text

STILL_SUFFIX = "-still.png"   # beside its video: a frame of `NAME.mp4` is `NAME-still.png`


def still(video: Path) -> Path | None:
    """A PNG of the video's middle frame, written beside it, or None when no frame can be read. A Markdown viewer
    plays no video, and one frame shows what the video holds; the middle one, since the first is the start line."""
    capture = cv2.VideoCapture(str(video))
    try:
        middle = int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) // 2
        capture.set(cv2.CAP_PROP_POS_FRAMES, middle)
        ok, bgr = capture.read()
    finally:
        capture.release()
    if not ok:
        return None
    path = video.with_name(video.stem + STILL_SUFFIX)
    write_png(path, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    return path


class Page:
    """The report's Markdown pieces, every path written relative to the report's folder."""

    def __init__(self, out: Path):
        self.out = out

    def rel(self, path: Path) -> str:
        return path.relative_to(self.out).as_posix()

    def picture(self, path: Path, caption: str) -> str:
        """An image shown inline, its caption under it (alt text alone is not shown by every viewer)."""
        if not path.exists():
            return f"*{caption}: not made.*"
        return f"![{caption}]({self.rel(path)})  \n*{caption}*"

    def pictures(self, folder: Path, pattern: str, caption: str) -> str:
        """Every image of a folder that matches, side by side on one line, then one caption naming them."""
        items = sorted(folder.glob(pattern))
        if not items:
            return f"*{caption}: none.*"
        shown = " ".join(f"![{p.stem}]({self.rel(p)})" for p in items)
        return f"{shown}  \n*{caption}: {', '.join(p.name for p in items)}*"

    def video(self, path: Path, caption: str) -> str:
        """A video's still, which opens the video when clicked, and the video's link under it."""
        if not path.exists():
            return f"*{caption}: not made.*"
        link = f"[{path.name}]({self.rel(path)})"
        frame = still(path)
        if frame is None:
            return f"*{caption}*: {link} (no frame could be read for a still)"
        return f"[![{caption}, its middle frame]({self.rel(frame)})]({self.rel(path)})  \n*{caption}*: {link}"

    def videos(self, folder: Path, pattern: str, caption: str) -> str:
        return "\n\n".join(self.video(p, f"{caption} ({p.stem})") for p in sorted(folder.glob(pattern)))


def _table_mae(hw: Path) -> str:
    lines = (hw / "evaluate" / "mae.md").read_text().split("\n")
    start = next(i for i, line in enumerate(lines) if line.startswith("| model"))
    end = next(i for i in range(start, len(lines)) if not lines[i].startswith("|"))
    return "\n".join(lines[start:end])


NETS = (("multinet", "MultiNet"), ("mtl-direct", "MTL (direct)"))


def _table_autonomy(sw: Path) -> str:
    rows = ["| network | mode | autonomy % | corrections [s] | elapsed [s] | take-overs | collisions | distance [m] | "
            "video |", "|---|---|---:|---:|---:|---:|---:|---:|---|"]
    for net, title in NETS:
        r = json.loads((sw / f"autonomy-{net}" / "autonomy.json").read_text())["rounds"][0]
        video = f"[video](sidewalk/autonomy-{net}/autonomy-0.mp4)"
        rows.append(f"| {title} | direct | {r['autonomy_percent']:.2f} | {r['correction_s']:.1f} | "
                    f"{r['elapsed_s']:.1f} | {r['corrections']} | {r['collisions']} | {r['distance_m']:.0f} | "
                    f"{video} |")
    rows.append("| *paper: MultiNet / MTL* | *direct* | *92.68 / 84.27* | | | | | | |")
    return "\n".join(rows)


def _metrics(path: Path, keys) -> str:
    m = json.loads((path / "metrics.json").read_text())
    return ", ".join(f"{k} {m[k]}" for k in keys if k in m)


def _headline(page: Page, seconds: float, quick: bool) -> str:
    """The opening and the two headline tables, each with the pictures that show what it measures."""
    hw, sw = page.out / "highway", page.out / "sidewalk"
    autonomy = "\n\n".join(page.video(sw / f"autonomy-{net}" / "autonomy-0.mp4", f"{title} driving the held-out "
                                      "loop, the expert correcting") for net, title in NETS)
    quick_note = ("A quick run (`drivestudio demo --quick`): every step at its smallest; the numbers show that it "
                  "works, not how well. " if quick else "")
    return f"""# drivestudio demo report

{quick_note}Made in {seconds / 60:.1f} minutes on this machine. The commands are in [commands.txt](commands.txt).

## Highway: mean absolute error per indicator (test split: 1, 2 and 3 lanes)

{_table_mae(hw)}

MAE in metres (angle in radians) on the demo's test episodes, beside Liu and Wang's Table 3 (10,000 TORCS frames: a
reference, not a like-for-like comparison). The demo's MobileNet trains for minutes, the paper's AlexNet for hours.

{page.picture(hw / "evaluate" / "mae.png", "MAE per indicator, the demo's models beside the paper's")}

Full report: [mae.md](highway/evaluate/mae.md), by regime and lane count in [evaluate/](highway/evaluate/).

## Sidewalk: percentage autonomy in direct mode

{_table_autonomy(sw)}

Autonomy = (1 - correction time / elapsed time) * 100 (Chowdhuri, Pankaj and Zipser, MultiNet), on the held-out
loop `procedural:907` with obstacles, the expert correcting by the documented rule (docs/sidewalk.md). Short demo
trainings: see docs/results.md for the study at a larger size.

{autonomy}
"""


def _highway(page: Page) -> str:
    hw = page.out / "highway"
    return f"""### Highway

{page.pictures(hw, "frame-*.png", "Frames of three tracks after SUMO's traffic has filled them")}

{page.video(hw / "oracle-drive.mp4", "The oracle driving over shared memory")};
{_metrics(hw / "oracle-drive", ("distance_m", "mean_speed_mps", "collisions", "off_road_events", "overtakes",
                                "loop_rate_hz"))}

The dataset ([stats](highway/stats/stats.md)):

{page.picture(hw / "stats" / "histograms.png", "What the dataset covers, indicator by indicator")}

{page.pictures(hw / "models", "*.png", "Training curves")}

{page.pictures(hw / "overlays", "*.png", "The MobileNet's worst test frames: the truth in filled boxes, its "
               "estimate in outlines")}

{page.video(hw / "mobilenet-drive.mp4", "The MobileNet driving closed loop")};
{_metrics(hw / "mobilenet-drive", ("distance_m", "mean_speed_mps", "collisions", "off_road_events", "loop_rate_hz"))}
"""


def _sidewalk(page: Page) -> str:
    sw = page.out / "sidewalk"
    return f"""### Sidewalk

{page.pictures(sw, "stereo-*.png", "The stereo pair of a park path")}

{page.videos(sw, "expert-*.mp4", "An expert mode driving")}

The data-moment set ([stats](sidewalk/stats/stats.md)):

{page.picture(sw / "stats" / "histograms.png", "Mode balance, steering and motor spread")}

{page.pictures(sw / "models", "*.png", "Validation curves")}

The exported MultiNet: [multinet.onnx](sidewalk/models/multinet.onnx)
"""


def write_report(out: Path, seconds: float, quick: bool) -> Path:
    """REPORT.md in the demo's folder: the headline tables, then everything else the demo made."""
    page = Page(out)
    text = f"{_headline(page, seconds, quick)}\n## Everything else\n\n{_highway(page)}\n{_sidewalk(page)}"
    path = out / "REPORT.md"
    write_text(path, text)
    return path
