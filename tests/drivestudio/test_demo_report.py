"""The demo's REPORT.md shows its pictures (drivestudio/commands/demo_report.py): every picture it names is an image
inline, every path it names exists, and every video has a still beside its link. Made in process from a small
stand-in of the demo's folder, so no demo runs (tests/drivestudio/test_demo.py runs the whole demo, marked slow)."""
import json
import re
from pathlib import Path

import cv2
import numpy as np

from drivestudio.commands.demo_report import STILL_SUFFIX, still, write_report
from drivestudio.outputs import VideoWriter, write_png, write_text

VIDEOS = ("highway/oracle-drive.mp4", "highway/mobilenet-drive.mp4", "sidewalk/expert-direct.mp4",
          "sidewalk/expert-follow.mp4", "sidewalk/expert-furtive.mp4", "sidewalk/autonomy-multinet/autonomy-0.mp4",
          "sidewalk/autonomy-mtl-direct/autonomy-0.mp4")
PICTURES = ("highway/evaluate/mae.png", "highway/frame-oval-3lanes.png", "highway/frame-sbends-1lane.png",
            "highway/stats/histograms.png", "highway/models/gist.pt.loss.png",
            "highway/overlays/overlay-ep0029-0000.png", "highway/overlays/overlay-ep0089-0003.png",
            "sidewalk/stereo-left.png", "sidewalk/stereo-right.png", "sidewalk/stats/histograms.png",
            "sidewalk/models/multinet.pt.loss.png")
GREYS = (40, 90, 140, 190, 240)   # one grey per frame: the middle frame is 140


def _video(path: Path) -> None:
    video = VideoWriter(path)
    for grey in GREYS:
        video.write(np.full((48, 64, 3), grey, np.uint8))
    video.close()


def _demo_folder(out: Path) -> None:
    """What the report reads: the pictures, videos, tables and metrics the demo's steps write."""
    for name in PICTURES:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        write_png(out / name, np.zeros((8, 8, 3), np.uint8))
    for name in VIDEOS:
        _video(out / name)
    write_text(out / "highway/evaluate/mae.md", "# MAE\n\n| model | angle |\n|---|---|\n| GIST + ridge | 0.05 |\n\n")
    for run in ("highway/oracle-drive", "highway/mobilenet-drive"):
        (out / run).mkdir()
        write_text(out / run / "metrics.json", json.dumps({"distance_m": 100.0, "collisions": 0}))
    for net in ("multinet", "mtl-direct"):
        write_text(out / f"sidewalk/autonomy-{net}/autonomy.json", json.dumps({"rounds": [{
            "autonomy_percent": 80.0, "correction_s": 2.0, "elapsed_s": 10.0, "corrections": 1, "collisions": 0,
            "distance_m": 20.0}]}))
    for name in ("commands.txt", "highway/stats/stats.md", "sidewalk/stats/stats.md", "sidewalk/models/multinet.onnx"):
        write_text(out / name, "x\n")


def test_the_report_shows_every_picture_inline_and_names_only_files_that_exist(tmp_path):
    _demo_folder(tmp_path)
    text = write_report(tmp_path, 60.0, quick=True).read_text()
    images = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    links = re.findall(r"\]\(([^)]+)\)", text)
    for target in links:
        assert (tmp_path / target).exists(), target
    shown = set(images)
    assert set(PICTURES) <= shown                                      # every picture the demo made is shown
    assert not [t for t in links if t.endswith(".png") and t not in shown]   # and none is only linked
    for name in VIDEOS:
        assert name in links                                           # each video is linked ...
        assert name.replace(".mp4", STILL_SUFFIX) in shown             # ... beside a still of it
    assert text.index("mae.png") < text.index("## Sidewalk")           # the MAE plot by the MAE table
    assert text.index("autonomy-0" + STILL_SUFFIX) < text.index("## Everything else")   # autonomy's by its table


def test_a_still_is_the_middle_frame_of_its_video(tmp_path):
    _video(tmp_path / "run.mp4")
    frame = still(tmp_path / "run.mp4")
    assert frame == tmp_path / ("run" + STILL_SUFFIX)
    grey = cv2.imread(str(frame)).mean()
    assert abs(grey - GREYS[len(GREYS) // 2]) < 20, grey


def test_a_video_without_a_readable_frame_is_linked_without_a_still(tmp_path):
    (tmp_path / "broken.mp4").write_bytes(b"not a video")
    assert still(tmp_path / "broken.mp4") is None
