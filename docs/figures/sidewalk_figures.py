"""The pictures of docs/sidewalk.md, made from the world itself (`python docs/figures/sidewalk_figures.py`).

    sidewalk-cameras.png      left and right frames: a park, a sidewalk, a forest path and a procedural loop
    sidewalk-modes.png        the same place driven three ways: trajectories from above, speed over time
    sidewalk-stereo.png       a post straight ahead: its disparity, measured against the geometry's prediction
    sidewalk-correction.png   correctional operation: the poor driver, and where the expert took over, under each rule
    multinet-figure7.png      the MultiNet study's Figure 7 and 8 (`... sidewalk_figures.py multinet out/study`)
    multinet-figure8.png
    sidewalk-moment.png       one data moment: four images and the next ten steering and motor values
    sidewalk-video.png        a frame of `drive --record`: both cameras and the top-down view
"""
from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import cv2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from controller.sidewalk import PoorDriver, SidewalkExpert  # noqa: E402
from core.worlds.sidewalk import SIDEWALK  # noqa: E402
from sim.sidewalk.car import CarState  # noqa: E402
from sim.sidewalk.stereo import PITCH_DEG, StereoConfig  # noqa: E402
from sim.sidewalk.topdown import TopDown  # noqa: E402
from sim.sidewalk.world import SidewalkConfig, SidewalkWorld  # noqa: E402

OUT = ROOT / "docs" / "img"
IX = {n: SIDEWALK.index(n) for n in SIDEWALK.truth_names}


def save(name: str, rgb: np.ndarray) -> None:
    cv2.imwrite(str(OUT / name), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print("wrote", OUT / name)


def label(img: np.ndarray, text: str) -> np.ndarray:
    img = img.copy()
    (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.42, 1)
    img[2:8 + h, 2:10 + w] = (img[2:8 + h, 2:10 + w] * 0.35).astype(np.uint8)
    cv2.putText(img, text, (6, 4 + h), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def drive(world, seconds: float, driver=None):
    driver = driver or SidewalkExpert()
    obs = world.observe(False)
    out = [obs.record]
    for _ in range(int(round(seconds / world.dt))):
        act = driver.action(obs.record) if hasattr(driver, "action") else np.array(driver.act(obs.record))
        obs = world.step(act, False)
        out.append(obs.record)
    return obs, np.array(out)


def cameras() -> None:
    rows = []
    for path, seed, mode, secs in (("park", 24, "direct", 8.0), ("sidewalk", 30, "follow", 6.0),
                                   ("forest", 12, "furtive", 10.0), ("procedural:7", 21, "direct", 12.0)):
        w = SidewalkWorld(SidewalkConfig(path=path, seed=seed, mode=mode, render=False))
        drive(w, secs)
        left, right = w.observe(True).frames
        text = f"{path}, {w.renderer.look.time}, {mode}"
        rows.append(np.hstack([label(left, "left: " + text), np.full((188, 4, 3), 255, np.uint8),
                               label(right, "right")]))
        rows.append(np.full((4, rows[-1].shape[1], 3), 255, np.uint8))
    save("sidewalk-cameras.png", np.vstack(rows[:-1]))


def modes() -> None:
    """The three experts over the same 45 m of the park path, from the same start: lateral offset along the path
    (the path unrolled: borders and obstacles where they stand), and speed over time."""
    fig, (top, speed) = plt.subplots(2, 1, figsize=(12, 7.2), gridspec_kw={"height_ratios": [1, 1]})
    colours = {"direct": "tab:blue", "follow": "tab:orange", "furtive": "tab:green"}
    span = 45.0
    layout = None
    for mode in ("direct", "follow", "furtive"):
        w = SidewalkWorld(SidewalkConfig(path="park", seed=3, mode=mode, render=False))
        layout = w.layout
        _, rec = drive(w, 50.0)
        along = (rec[:, IX["s"]] - layout.start_s) % layout.path.length
        keep = along < span
        top.plot(along[keep], rec[keep, IX["d"]], color=colours[mode], lw=1.8, label=mode)
        t = np.arange(len(rec)) * w.dt
        speed.plot(t, rec[:, IX["speed"]], color=colours[mode], lw=1.4, label=mode)
        if mode == "follow":
            speed.plot(t, rec[:, IX["lead_speed"]], color=colours[mode], lw=0.9, ls=":", label="lead car")
            top.plot(along[keep], rec[keep, IX["lead_d"]], color=colours[mode], lw=0.9, ls=":", label="lead car")
        if mode == "furtive":
            bordered = np.minimum(rec[:, IX["border_left"]], rec[:, IX["border_right"]]) < 5
            speed.fill_between(t, 0, 4.0, where=~bordered, color="tab:green", alpha=0.1, lw=0,
                               label="furtive: no border beside it")
    hw = layout.path.half_width
    s0, length = layout.start_s, layout.path.length
    for d in (-hw, hw):
        top.axhline(d, color="0.5", lw=0.8)
    for b in layout.borders:
        for k in range(len(b.starts)):
            a, e = (b.starts[k] - s0) % length, (b.ends[k] - s0) % length
            if e < a:       # a stretch the start lies in
                a = 0.0
            if a < span:
                top.fill_between([a, min(e, span)], b.face[k], b.face[k] + b.side * 0.5, color="darkgreen",
                                 alpha=0.5, lw=0)
    for o in layout.obstacles:
        a = (o.s - s0) % length
        if a < span:
            top.add_patch(plt.Rectangle((a - o.along / 2, o.d - o.across / 2), o.along, o.across, color="firebrick"))
            top.text(a, o.d + o.across / 2 + 0.08, o.kind, ha="center", fontsize=8, color="firebrick")
    top.set_xlim(0, span)
    top.set_ylim(-hw - 0.6, hw + 0.6)
    top.set_xlabel("along the path from the start [m]")
    top.set_ylabel("d [m], + left")
    top.set_title("the same 45 m three ways: path edges grey, hedges and bushes green, obstacles red")
    top.legend(loc="lower right", fontsize=8, ncol=4)
    speed.set_xlabel("t [s]")
    speed.set_ylabel("speed [m/s]")
    speed.set_ylim(0, 4.0)
    speed.set_title("speed: direct cruises, follow keeps 1.2 m behind the lead car, furtive creeps beside borders")
    speed.legend(loc="upper right", fontsize=8, ncol=2)
    fig.tight_layout()
    fig.savefig(OUT / "sidewalk-modes.png", dpi=90)
    plt.close(fig)
    print("wrote", OUT / "sidewalk-modes.png")


def stereo() -> None:
    st = StereoConfig()
    row = int(st.camera("left").horizon_row())
    distances = np.array([1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0])
    measured, crops = [], []
    from tests.sidewalk.helpers import world  # the stereo test's stadium set-up
    for dist in distances:
        frames = []
        for items in ([("post", 10.0 + 0.1 + dist, 0.0, 0.0)], []):
            w = world(obstacles=items, borders=((), ()), start_s=10.0, render=True)
            w.car = CarState(s=10.0)
            frames.append(w.observe().frames)
        centres = []
        for a, b in zip(*frames):
            cols = np.flatnonzero(np.any(a[row] != b[row], axis=-1))
            centres.append((cols.min() + cols.max()) / 2)
        measured.append(centres[0] - centres[1])
        if dist == 2.0:
            crops = [f[row - 40:row + 40, 118:218] for f in frames[0]]
    predicted = st.disparity(1.0) / (distances * math.cos(math.radians(PITCH_DEG)))
    fig, (img, plot) = plt.subplots(1, 2, figsize=(11, 3.6), gridspec_kw={"width_ratios": [1, 1.3]})
    both = np.hstack([crops[0], np.full((80, 3, 3), 255, np.uint8), crops[1]])
    img.imshow(both)
    img.axhline(40, color="yellow", lw=0.7)
    img.set_title("a post 2 m ahead: left | right (eye-height row in yellow)")
    img.axis("off")
    dd = np.linspace(0.9, 10.5, 100)
    plot.plot(dd, st.disparity(1.0) / (dd * math.cos(math.radians(PITCH_DEG))), color="0.4",
              label="baseline x focal / depth")
    plot.plot(distances, measured, "o", color="tab:red", label="measured on the frames")
    plot.set_xlabel("distance ahead [m]")
    plot.set_ylabel("disparity [px]")
    plot.set_title(f"B = {st.baseline} m, f = {st.focal_px:.1f} px: within "
                   f"{np.abs(np.array(measured) - predicted).max():.2f} px")
    plot.legend()
    fig.tight_layout()
    fig.savefig(OUT / "sidewalk-stereo.png", dpi=90)
    plt.close(fig)
    print("wrote", OUT / "sidewalk-stereo.png")


def correction() -> None:
    """The poor driver on the park path for 60 s under each correction rule: its lateral offset, and where the expert
    took over, coloured by the clause that made it take over."""
    from controller.sidewalk.correction import CLAUSES
    from drivestudio.worlds.sidewalk.drivers import Supervisor
    colours = {"leaving the path": "tab:orange", "imminent collision": "tab:red", "stalled": "tab:purple",
               "deviating from the expert": "tab:olive"}
    fig, axes = plt.subplots(2, 1, figsize=(11, 5.6), sharex=True)
    for ax, rule in zip(axes, ("safety", "strict")):
        w = SidewalkWorld(SidewalkConfig(path="park", seed=2, render=False))
        poor, sup = PoorDriver(seed=4), Supervisor(w, "correctional", rule)
        obs = w.observe(False)
        rec, why = [], []
        for _ in range(int(60 / w.dt)):
            applied, _ = sup(obs, np.array(poor.act(obs.record)))
            why.append(sup.rule.clause)
            obs = w.step(applied, False)
            rec.append(obs.record)
        rec = np.array(rec)
        t = np.arange(1, len(rec) + 1) * w.dt
        hw = w.path.half_width
        for clause in CLAUSES[rule]:
            ax.fill_between(t, -hw, hw, where=np.array(why) == clause, color=colours[clause], alpha=0.35, lw=0,
                            label=f"the expert corrects: {clause}")
        ax.plot(t, rec[:, IX["d"]], color="tab:blue", lw=1.2, label="lateral offset d")
        ax.axhline(hw, color="0.4", lw=0.8)
        ax.axhline(-hw, color="0.4", lw=0.8)
        share = rec[:, IX["correcting"]].mean()
        hits = int(np.sum(np.diff(rec[:, IX["collision"]], prepend=0) > 0))
        ax.set_title(f"rule '{rule}': autonomy {100 * (1 - share):.1f} %, {hits} collision(s), "
                     f"{rec[:, IX['off_path']].mean() * 60:.1f} s off the path", fontsize=10)
        ax.set_ylabel("d [m] (edges grey)")
        ax.legend(loc="lower right", fontsize=7, ncol=2)
    axes[-1].set_xlabel("t [s]")
    fig.suptitle("the poor driver on the park path under the two correction rules", fontsize=11)
    fig.tight_layout()
    fig.savefig(OUT / "sidewalk-correction.png", dpi=90)
    plt.close(fig)
    print("wrote", OUT / "sidewalk-correction.png")


def multinet(study: str = "out/study") -> None:
    """The paper's Figures 7 and 8 from a finished study (`drivestudio study --out STUDY`)."""
    import json

    from drivestudio.worlds.sidewalk.study_report import figures
    validation = json.loads((Path(study) / "study.json").read_text())["validation"]
    f7, f8 = figures(OUT, validation["multinet"], validation["mtl"])
    f7.replace(OUT / "multinet-figure7.png")
    f8.replace(OUT / "multinet-figure8.png")
    print("wrote", OUT / "multinet-figure7.png", OUT / "multinet-figure8.png")


def moment() -> None:
    import subprocess

    from perception.datasets import FrameDataset
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "drivestudio", "generate", "--world", "sidewalk", "--frames", "120",
                        "--episode-frames", "40", "--paths", "park", "--seed", "7", "--out", f"{tmp}/d",
                        "--workers", "2"], check=True, cwd=ROOT)
        ds = FrameDataset(f"{tmp}/d", None, normalised=False)
        i = 2 * len(ds) // 3 + 12    # a furtive moment
        images, mode, target = ds[i]
    x = images.numpy()
    tiles = [x[3 * k:3 * k + 3].transpose(1, 2, 0) for k in range(4)]
    names = ["left, t - 33 ms", "right, t - 33 ms", "left, t", "right, t"]
    fig = plt.figure(figsize=(12, 4.6))
    for k in range(4):
        ax = fig.add_subplot(2, 3, [1, 2, 4, 5][k])
        ax.imshow(tiles[k])
        ax.set_title(names[k], fontsize=9)
        ax.axis("off")
    ax = fig.add_subplot(1, 3, 3)
    steps = np.arange(1, 11) * 33
    ax.plot(steps, target[:10].numpy(), "o-", label="steer")
    ax.plot(steps, target[10:].numpy(), "s-", label="motor")
    ax.set_ylim(0.3, 0.8)
    ax.set_xlabel("ms after t")
    ax.set_title(f"targets ({['direct', 'follow', 'furtive'][int(mode)]} mode)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(OUT / "sidewalk-moment.png", dpi=90)
    plt.close(fig)
    print("wrote", OUT / "sidewalk-moment.png")


def video() -> None:
    from drivestudio.worlds.sidewalk.video import compose
    w = SidewalkWorld(SidewalkConfig(path="park", seed=3, mode="follow", render=False))
    obs, _ = drive(w, 12.0)
    obs = w.observe(True)
    r = SIDEWALK.unpack(obs.record)
    top = TopDown(w.layout, 188, 14.0).draw(r["x"], r["y"], r["yaw"], w.lead.state)
    a = SidewalkExpert().action(obs.record)
    save("sidewalk-video.png", compose(*obs.frames, top, f"t {obs.t:5.1f} s  follow  expert  {r['speed']:4.2f} m/s  "
                                       f"steer {a[0]:.2f}  motor {a[1]:.2f}  expert"))


JOBS = {f.__name__: f for f in (cameras, modes, stereo, correction, moment, video)}

if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    if sys.argv[1:2] == ["multinet"]:        # sidewalk_figures.py multinet [STUDY]: Figures 7 and 8 of a study
        multinet(*sys.argv[2:3])
    else:                                    # sidewalk_figures.py [NAME ...]: those pictures, or all but the study's
        for name in sys.argv[1:] or list(JOBS):
            JOBS[name]()
