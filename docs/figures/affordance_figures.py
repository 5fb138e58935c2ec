"""Draw the pictures of docs/affordances.md and docs/controller.md from the project's own code.

Re-run from the repository root with `.venv/bin/python docs/figures/affordance_figures.py`; it needs no network
and no display (matplotlib's Agg backend) and rewrites docs/img/affordances-*.png and docs/img/controller-*.png.
Every number in the pictures is computed here, not typed: the indicators by `sim.highway.truth.affordances` on a track
built with `sim.track.track_from_spec`, the rear labels by `sim.highway.truth.rear_indicators`, the markings and lane
centres by the track, the follow curve by `ChenController.follow_speed`, the safe gap by `lookout.safe_gap`, the
steering curve and the overtakes by running `ChenController` on the exact indicators (the overtakes also drive the
host car's kinematic model). Edit a scene in SCENES or REAR_SCENES below and re-run.
"""
from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch, Polygon, Rectangle  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

# --- the project's code: every import of it, in one place -------------------------------------------------------
from controller.highway.chen import ChenController, ChenParams  # noqa: E402
from controller.highway.lookout import LookoutParams, crossing, safe_gap  # noqa: E402
from core.worlds.highway import HOST_LENGTH, INACTIVE, INDICATORS, REAR, REAR_RANGE  # noqa: E402  (the declaration)
from sim.highway.truth import affordances, rear_indicators  # noqa: E402
from sim.highway.vehicle import VehicleState, step_vehicle  # noqa: E402
from sim.track import VERGE_WIDTH, track_from_spec  # noqa: E402

OUT = ROOT / "docs" / "img"
DPI = 100
LANE_WIDTH = 4.0
EGO_S = 100.0      # [m] the host car's s in every scene: 400 m of the first straight lie ahead (fast = 1)
CAR = (4.6, 1.9)   # [m] length, width of a car box (the host car's body)
DASH = (4.0, 10.0)  # [m] dash length and period of the internal markings, as on the rendered road

# colours
ROAD, VERGE, LINE = "#5b5d63", "#9fc48a", "white"
IN_LANE, ON_MARKING, ANGLE, HOST, OTHER, GREY = "#1f5fbf", "#d9730d", "#7a1fa2", "#d62728", "#f2c200", "#8c8c8c"


def demo_track(lanes: int):
    """A long straight loop (the shape of the `oval` preset): 500 m straights, 150 m radius half circles."""
    return track_from_spec({"name": f"demo-{lanes}-lanes", "lanes": lanes, "lane_width": LANE_WIDTH, "segments": [
        {"type": "straight", "length": 500}, {"type": "arc", "radius": 150, "angle_deg": 180, "turn": "left"},
        {"type": "straight", "length": 500}, {"type": "arc", "radius": 150, "angle_deg": 180, "turn": "left"}]})


# --- the scenes ---------------------------------------------------------------------------------------------------
@dataclass
class Scene:
    file: str
    title: str
    lanes: int
    d: float                 # [m] host car's lateral offset, positive left
    heading: float           # [rad] host car's yaw relative to the tangent, counter-clockwise positive
    cars: tuple              # ((gap along s [m], d [m]), ...) of the other cars


SCENES = [
    Scene("affordances-in-lane.png", "In lane: only the in-lane system (indicators 2-8) is active",
          3, -0.4, 0.05, ((18.0, 0.0), (31.0, 4.0), (12.0, -4.0), (60.0, -4.1), (85.0, 0.2))),
    Scene("affordances-on-marking.png", "On a marking: only the on-marking system (indicators 9-13) is active",
          3, 2.2, 0.12, ((15.0, 4.0), (27.0, 0.3), (9.0, -4.0))),
    Scene("affordances-overlap.png", "In the overlap: both systems are active",
          3, 1.3, 0.04, ((22.0, 4.2), (35.0, 0.0), (14.0, -3.8))),
    Scene("affordances-1-lane.png", "One lane: the host car 0.8 m onto the left verge (on-marking system, left edge)",
          1, 2.8, -0.15, ((25.0, 0.3),)),
    Scene("affordances-2-lanes.png", "Two lanes: the host car in the right lane (no lane to its right)",
          2, -2.3, 0.03, ((20.0, 2.0), (41.0, -2.2))),
    Scene("affordances-3-lanes.png", "Three lanes: right lane, near the right edge (overlap with the edge band)",
          3, -5.3, 0.03, ((26.0, 4.0), (16.0, 0.0), (33.0, -4.2))),
    Scene("affordances-4-lanes.png", "Four lanes: second lane from the left (every neighbour exists)",
          4, 2.5, -0.06, ((24.0, 6.0), (38.0, 2.0), (11.0, -2.0), (50.0, -6.0))),
]


def indicators(track, d, heading, cars) -> dict[str, float]:
    cars = np.asarray(cars, dtype=float).reshape(-1, 2)
    v = affordances(track, EGO_S, d, heading, EGO_S + cars[:, 0], cars[:, 1])
    return dict(zip(INDICATORS, (float(x) for x in v)))


def systems(v: dict[str, float]) -> tuple[bool, bool]:
    """(in-lane active, on-marking active), read from the indicators themselves."""
    return v["toMarking_ML"] != INACTIVE["toMarking_ML"], v["toMarking_M"] != INACTIVE["toMarking_M"]


# --- drawing the road ---------------------------------------------------------------------------------------------
def car_polygon(d, ds, heading, **kw):
    """A car box centred at (d, ds), its nose turned `heading` rad counter-clockwise (to the left, +d)."""
    length, width = CAR
    f = np.array([math.sin(heading), math.cos(heading)])    # forward, in (d, s)
    left = np.array([math.cos(heading), -math.sin(heading)])
    c = np.array([d, ds])
    pts = [c + f * length / 2 + left * width / 2, c + f * length / 2 - left * width / 2,
           c - f * length / 2 - left * width / 2, c - f * length / 2 + left * width / 2]
    return Polygon(pts, closed=True, **kw)


def draw_road(ax, track, y0, y1):
    """Verges, road, solid edges, dashed internal markings and dotted lane centres between ds = y0 and y1."""
    m, c = track.markings, track.lane_centres
    ax.add_patch(Rectangle((m[-1] - VERGE_WIDTH, y0), m[0] - m[-1] + 2 * VERGE_WIDTH, y1 - y0, color=VERGE, zorder=0))
    ax.add_patch(Rectangle((m[-1], y0), m[0] - m[-1], y1 - y0, color=ROAD, zorder=0))
    for x in (m[0], m[-1]):
        ax.plot([x, x], [y0, y1], color=LINE, lw=2.2, zorder=1, solid_capstyle="butt")
    # dashes where (s mod period) < dash, s = EGO_S + ds
    first = math.floor((EGO_S + y0) / DASH[1]) * DASH[1] - EGO_S
    for x in m[1:-1]:
        for start in np.arange(first, y1, DASH[1]):
            a, b = max(start, y0), min(start + DASH[0], y1)
            if b > a:
                ax.plot([x, x], [a, b], color=LINE, lw=2.0, zorder=1, solid_capstyle="butt")
    for x in c:
        ax.plot([x, x], [y0, y1], color="#d8d8d8", lw=0.8, ls=(0, (1, 3)), zorder=1)


def dimension(ax, y, x_from, x_to, text, color, above=True):
    """A dimension line from x_from to x_to at height y, labelled."""
    ax.add_patch(FancyArrowPatch((x_from, y), (x_to, y), arrowstyle="<|-|>", mutation_scale=9, lw=1.4,
                                 color=color, zorder=6, shrinkA=0, shrinkB=0))
    ax.plot([x_to, x_to], [y - 0.45, y + 0.45], color=color, lw=1.4, zorder=6)
    ax.text((x_from + x_to) / 2, y + (0.3 if above else -0.3), text, color=color, fontsize=10, ha="center",
            va="bottom" if above else "top", zorder=7, fontweight="bold",
            bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.85))


IN_LANE_ROWS = {"toMarking_RR": 9.6, "toMarking_LL": 8.1, "toMarking_MR": 6.6, "toMarking_ML": 5.1}
ON_MARKING_ROWS = {"toMarking_M": -4.0, "toMarking_L": -5.5, "toMarking_R": -7.0}


def panel_at_host(ax, track, s: Scene, v):
    """Left panel: the cross-section around the host car, to scale, with the toMarking and angle dimensions."""
    half = max(track.half_width + VERGE_WIDTH + 0.6, 7.5)
    y0, y1 = -12.6, 11.2
    draw_road(ax, track, y0, y1)
    in_lane, on_marking = systems(v)
    # the host's lateral position, through all rows
    ax.plot([s.d, s.d], [y0 + 0.2, y1 - 0.2], color="black", lw=0.8, ls=(0, (4, 3)), zorder=5)
    ax.add_patch(car_polygon(s.d, 0.0, s.heading, fc=HOST, ec="black", lw=1.2, zorder=8))
    # angle: the tangent, the car's axis and the value
    tip = (s.d + 3.4 * math.sin(s.heading), 3.4 * math.cos(s.heading))
    ax.annotate("", xy=tip, xytext=(s.d, 0.0), zorder=9,
                arrowprops=dict(arrowstyle="-|>", color=ANGLE, lw=1.8, mutation_scale=12, shrinkA=0, shrinkB=0))
    right_half = s.d < 0  # the label goes on the side of the car with more room
    ax.text(s.d + (0.5 if right_half else -0.5), 3.0, f"angle = {v['angle'] + 0.0:+.2f} rad", color=ANGLE,
            fontsize=10, fontweight="bold", ha="right" if right_half else "left", va="center", zorder=9,
            bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.85))
    # toMarking dimensions: the marking lies at d - value
    for name, y in IN_LANE_ROWS.items():
        if in_lane and v[name] != INACTIVE[name]:
            dimension(ax, y, s.d, s.d - v[name], f"{name} = {v[name]:+.2f}", IN_LANE)
    for name, y in ON_MARKING_ROWS.items():
        if on_marking and v[name] != INACTIVE[name]:
            dimension(ax, y, s.d, s.d - v[name], f"{name} = {v[name]:+.2f}", ON_MARKING, above=False)
    # where each system is active across the road, sampled from the indicators themselves
    ds_grid = np.arange(-half, half + 1e-9, 0.01)
    act = np.array([systems(indicators(track, float(x), 0.0, ())) for x in ds_grid])
    rows = ((IN_LANE, "in-lane\nactive", -9.6), (ON_MARKING, "on-marking\nactive", -11.2))
    for row, (col, _label, y) in enumerate(rows):
        on = act[:, row]
        edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            ax.add_patch(Rectangle((ds_grid[a], y - 0.45), ds_grid[b - 1] - ds_grid[a], 0.9, color=col, zorder=3))
    ax.set_yticks([y for _, _, y in rows])
    ax.set_yticklabels([label for _, label, _ in rows], fontsize=9, fontweight="bold")
    for tick, (col, _, _) in zip(ax.get_yticklabels(), rows):
        tick.set_color(col)
    ax.tick_params(axis="y", length=0)
    ax.plot([s.d], [-10.4], marker="v", color="black", ms=8, zorder=9)
    ax.set_xlim(half, -half)  # d positive to the LEFT: the x axis runs right to left
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xticks(track.markings)
    ax.set_xticklabels([f"m{j}\n{x:+g}" for j, x in enumerate(track.markings)], fontsize=9)
    top = ax.secondary_xaxis("top")
    top.set_xticks(track.lane_centres)
    top.set_xticklabels([f"lane {k}\nc{k} = {x:+g}" for k, x in enumerate(track.lane_centres)], fontsize=9)
    ax.set_xlabel("d [m], positive to the left", fontsize=9)
    ax.set_title("At the host car (to scale)", fontsize=11, pad=8)


def panel_ahead(ax, track, s: Scene, v):
    """Middle panel: the lanes ahead (along-track scale compressed) with the dist_* gaps."""
    half = track.half_width + VERGE_WIDTH + 0.4
    y0, y1 = -7.0, 78.0
    draw_road(ax, track, y0, y1)
    in_lane, on_marking = systems(v)
    ax.axhline(60.0, color="black", lw=1.0, ls=(0, (5, 3)), zorder=2)
    ax.text(half - 0.2, 60.5, "60 m cap", fontsize=9, ha="left", va="bottom", zorder=7,
            bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.8))
    for ds, cd in s.cars:
        ax.add_patch(car_polygon(cd, ds, 0.0, fc=OTHER, ec="black", lw=1, zorder=4))
    ax.add_patch(car_polygon(s.d, 0.0, 0.0, fc=HOST, ec="black", lw=1.2, zorder=8))  # unrotated: scales differ
    c, k = track.lane_centres, track.lane_of(s.d)
    gaps = []  # (name, lane, colour, side)
    if in_lane:
        gaps += [("dist_LL", k - 1, IN_LANE, +1), ("dist_MM", k, IN_LANE, +1), ("dist_RR", k + 1, IN_LANE, +1)]
    if on_marking:
        j = int(np.argmin(np.abs(track.markings - (s.d - v["toMarking_M"]))))  # the marking the car is on
        gaps += [("dist_L", j - 1, ON_MARKING, -1), ("dist_R", j, ON_MARKING, -1)]
    for name, lane, col, side in gaps:
        if not 0 <= lane < track.lanes or v[name] == INACTIVE[name]:
            continue
        x = c[lane] + side * 0.7
        ax.add_patch(FancyArrowPatch((x, 0.0), (x, v[name]), arrowstyle="-|>", mutation_scale=12, lw=1.8,
                                     color=col, zorder=6, shrinkA=0, shrinkB=0))
        label = f"{name} = {v[name]:.0f}" + (" (none within 60 m)" if v[name] == 60.0 else "")
        y_label = v[name] / 2 if v[name] >= 16.0 else v[name] + 9.0  # short gaps: above the car ahead
        ax.text(x + side * 0.6, y_label, label, color=col, fontsize=9.5, fontweight="bold",
                rotation=90, ha="center", va="center", zorder=7,
                bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.85))
    ax.set_xlim(half, -half)
    ax.set_ylim(y0, y1)
    ax.set_xticks(track.lane_centres)
    ax.set_xticklabels([f"lane {k}" for k in range(track.lanes)], fontsize=9)
    ax.set_ylabel("gap along the centreline [m]", fontsize=9)
    ax.tick_params(axis="y", labelsize=9)
    ax.set_title("Ahead (along-track scale compressed)", fontsize=11, pad=30)


def panel_values(ax, track, s: Scene, v):
    """Right panel: all 14 values, active ones in their system's colour, inactive ones grey."""
    ax.axis("off")
    in_lane, on_marking = systems(v)
    system_of = {n: "in-lane" for n in INDICATORS[1:8]} | {n: "on-marking" for n in INDICATORS[8:13]}
    units = {"angle": "rad", "fast": ""}
    y = 0.985
    ax.text(0.0, y, "The 14 indicators", fontsize=11, fontweight="bold", va="top", transform=ax.transAxes)
    y -= 0.06
    for name in INDICATORS:
        value = v[name]
        sysname = system_of.get(name)
        active = sysname is None or (in_lane if sysname == "in-lane" else on_marking)
        if name == "angle":
            text, col, note = f"{value:+.3f}", ANGLE, "rad"
        elif name == "fast":
            text, col, note = f"{value:.0f}", "black", "straight > 60 m ahead" if value else "no long straight"
        elif not active:
            text, col, note = f"{value:+g}", GREY, "inactive (system off)"
        elif value == INACTIVE[name]:
            side = "left" if name.endswith(("LL", "_L")) else "right"
            what = "no lane" if name.startswith("dist") or name.endswith(("LL", "RR")) else "no marking"
            text, col, note = f"{value:+g}", GREY, f"{what} on the {side}"
        else:
            text = f"{value:.1f} m" if name.startswith("dist") else f"{value:+.2f} m"
            col, note = (IN_LANE if sysname == "in-lane" else ON_MARKING), ""
        ax.text(0.0, y, f"{name:<13}", family="monospace", fontsize=10, color=col, va="top",
                transform=ax.transAxes, fontweight="bold" if col not in (GREY,) else "normal")
        ax.text(0.54, y, text, family="monospace", fontsize=10, color=col, va="top", ha="right",
                transform=ax.transAxes)
        ax.text(0.57, y, note or units.get(name, ""), fontsize=8.5, color=col if col != "black" else GREY,
                va="top", transform=ax.transAxes)
        y -= 0.0505
    y -= 0.02
    lane = int(track.lane_of(s.d))
    extra = [f"lanes_left = {lane}   lanes = {track.lanes}",
             f"in_lane = {in_lane}   on_marking = {on_marking}",
             f"off_road = {not track.on_road(s.d)}",
             f"host: d = {s.d:+.2f} m, heading = {s.heading:+.2f} rad"]
    for line in extra:
        ax.text(0.0, y, line, family="monospace", fontsize=9.5, va="top", transform=ax.transAxes)
        y -= 0.045
    y -= 0.015
    for col, line in ((IN_LANE, "blue: in-lane system"), (ON_MARKING, "orange: on-marking system"),
                      (GREY, "grey: inactive value")):
        ax.text(0.0, y, line, fontsize=9, color=col, va="top", transform=ax.transAxes)
        y -= 0.04


def draw_scene(s: Scene) -> None:
    track = demo_track(s.lanes)
    v = indicators(track, s.d, s.heading, s.cars)
    fig = plt.figure(figsize=(14.0, 8.0), dpi=DPI)
    gs = fig.add_gridspec(1, 3, width_ratios=[1.45, 0.95, 0.9], left=0.075, right=0.99, top=0.84, bottom=0.08,
                          wspace=0.12)
    panel_at_host(fig.add_subplot(gs[0]), track, s, v)
    panel_ahead(fig.add_subplot(gs[1]), track, s, v)
    panel_values(fig.add_subplot(gs[2]), track, s, v)
    fig.suptitle(f"{s.title}\n{s.lanes} lane{'s' if s.lanes > 1 else ''} of {LANE_WIDTH:g} m; host car (red) at "
                 f"d = {s.d:+.2f} m, heading {s.heading:+.2f} rad; other cars yellow; driving direction up",
                 fontsize=12, y=0.985)
    save(fig, s.file)


# --- the controller's pictures ----------------------------------------------------------------------------------------
def draw_follow_curve() -> None:
    ctrl, p = ChenController(3), ChenParams()
    dist = np.linspace(0.0, p.follow_gap, 301)
    speed = np.array([ctrl.follow_speed(float(x)) for x in dist])
    beyond = np.linspace(p.follow_gap, 25.0, 101)
    fig, ax = plt.subplots(figsize=(10.0, 5.6), dpi=DPI)
    ax.plot(dist, speed, color=IN_LANE, lw=2.5, label="slow_down = follow_speed(dist_MM)")
    ax.plot(beyond, [ctrl.follow_speed(float(x)) for x in beyond], color=IN_LANE, lw=1.5, ls=":",
            label=f"the curve beyond follow_gap = {p.follow_gap:g} m (not used: no limit there)")
    ax.axhline(p.v_max, color=GREY, lw=1, ls="--")
    ax.text(0.3, p.v_max + 0.3, f"v_max = {p.v_max:g} m/s", color=GREY, fontsize=10, va="bottom")
    ax.axvline(p.follow_gap, color="black", lw=1, ls="--")
    ax.text(p.follow_gap + 0.2, 2.0, f"dist_MM >= {p.follow_gap:g} m:\nnot following,\nslow_down unlimited",
            fontsize=10, va="bottom")
    for x in (5.0, 10.0, 15.0):
        y = ctrl.follow_speed(x)
        ax.plot([x], [y], "o", color=HOST, ms=7, zorder=5)
        ax.annotate(f"{x:g} m -> {y:.1f} m/s", (x, y), xytext=(-12, 12), textcoords="offset points",
                    ha="right", fontsize=10, color=HOST)
    # where a follower settles behind a leader at 8 m/s: follow_speed(gap) = 8 (bisection on the code's curve)
    lo, hi = 5.0, p.follow_gap
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if ctrl.follow_speed(mid) < 8.0 else (lo, mid)
    ax.plot([lo], [8.0], "s", color=ON_MARKING, ms=7, zorder=5)
    ax.annotate(f"behind a leader at 8 m/s the host\nsettles {lo:.1f} m back (centre to centre)", (lo, 8.0),
                xytext=(14, -34), textcoords="offset points", fontsize=10, color=ON_MARKING,
                arrowprops=dict(arrowstyle="-", color=ON_MARKING))
    ax.set_xlim(0, 25)
    ax.set_ylim(-0.5, 22)
    ax.set_xlabel("dist_MM: gap to the car ahead in the host's lane [m]", fontsize=11)
    ax.set_ylabel("slow_down: speed limit while following [m/s]", fontsize=11)
    ax.set_title(f"Rule 2, follow: slow_down = v_max (1 - exp(-follow_c / v_max * dist_MM - follow_d)), not below 0\n"
                 f"v_max = {p.v_max:g}, follow_c = {p.follow_c:g}, follow_d = {p.follow_d:g} "
                 "(computed by ChenController.follow_speed)", fontsize=11)
    ax.legend(loc="upper left", fontsize=10, bbox_to_anchor=(0.0, 0.93))
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save(fig, "controller-follow.png")


def draw_steering_curve() -> None:
    """Steer against the host car's offset from its lane centre, lane keeping on the exact indicators.

    Each point is a fresh controller that saw one frame 1 m to the same side of the centre lane (so it knows
    which lane it came from), then the frame at the offset, angle 0."""
    track = demo_track(3)
    centre = float(track.lane_centres[1])
    offsets = np.linspace(-3.4, 3.4, 681)
    steer, region = [], []
    for off in offsets:
        ctrl = ChenController(3)
        ctrl.act(affordances(track, EGO_S, centre + math.copysign(1.0, off), 0.0), 15.0)
        v = affordances(track, EGO_S, centre + off, 0.0)
        steer.append(ctrl.act(v, 15.0).steer)
        region.append(systems(dict(zip(INDICATORS, v))))
    steer = np.array(steer)
    fig, ax = plt.subplots(figsize=(11.0, 6.0), dpi=DPI)
    p = ChenParams()
    shades = {(True, False): ("#dce8f8", f"in-lane only: target (ML + MR) / 2, coe {p.coe_keep:g} "
                                         f"(left steers > {p.boost_above:g} boosted)"),
              (True, True): ("#e9dcf3", f"overlap: target (ML + MR) / 2, toMarking_M < {p.near_marking:g} "
                                        f"so coe {p.coe_keep_near_marking:g}"),
              (False, True): ("#fbe5d0", "on-marking only: target the lane it came from, (L + M) / 2 or "
                                         f"(R + M) / 2, coe {p.coe_on_marking:g}")}
    region = [tuple(r) for r in region]
    start = 0
    for i in range(1, len(offsets) + 1):
        if i == len(offsets) or region[i] != region[start]:
            ax.axvspan(offsets[start], offsets[i - 1], color=shades[region[start]][0], zorder=0)
            start = i
    for key in ((True, False), (True, True), (False, True)):
        ax.fill_between([], [], color=shades[key][0], label=shades[key][1])
    for x in (2.5, -2.5):
        ax.text(x + math.copysign(0.45, x), -0.35 if x > 0 else 0.4, "next lane's\nin-lane band:\nkeeps that\nlane",
                fontsize=8.5, ha="center", va="center")
    for j, x in enumerate(track.markings):
        if abs(x - centre) < 3:
            ax.axvline(x - centre, color="black", lw=1.2, ls="--")
            ax.text(x - centre, 1.04, f"marking m{j}", ha="center", va="bottom", fontsize=9)
    ax.plot(offsets, steer, color=HOST, lw=2.2, label="steer")
    ax.axhline(0, color="black", lw=0.8)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, fontsize=9, frameon=False)
    ax.set_xlim(offsets[-1], offsets[0])  # left of the centre is on the left
    ax.set_ylim(-1.1, 1.15)
    ax.set_xlabel("host car's offset from the centre lane's centre, d - c1 [m] (positive = left of it)", fontsize=11)
    ax.set_ylabel("steer (positive = left)", fontsize=11)
    ax.set_title("Lane keeping (rules 4 and 6) on three lanes, angle = 0: the car steers back towards its lane\n"
                 "computed by ChenController on the exact indicators", fontsize=11, pad=22)
    fig.tight_layout()
    save(fig, "controller-steering.png")


def overtake(lanes: int, seconds: float = 20.0):
    """The host car (18 m/s) in its lane meets a car at 8 m/s 40 m ahead; the Chen controller drives."""
    track = demo_track(lanes)
    lane = 1
    host = VehicleState(s=20.0, d=float(track.lane_centres[lane]), heading=0.0, speed=18.0)
    lead_s, lead_d, lead_v = host.s + 40.0, float(track.lane_centres[lane]), 8.0
    ctrl = ChenController(lanes)
    empty = affordances(track, host.s, host.d, host.heading)
    for _ in range(ctrl.params.timer_set + 1):  # a host already cruising: its neighbour lanes have proved clear
        ctrl.act(empty, host.speed)
    rows = []
    for i in range(int(round(seconds / 0.1))):
        v = affordances(track, host.s, host.d, host.heading, [lead_s], [lead_d])
        a = ctrl.act(v, host.speed)
        rows.append((i * 0.1, host.d, a.steer, host.speed, float(track.gap(host.s, lead_s)), ctrl.state))
        host = step_vehicle(host, a, 0.1, track)
        lead_s += lead_v * 0.1
    return track, rows


def draw_overtakes() -> None:
    state_colour = {"keep": "black", "left-1": IN_LANE, "left-2": "#16a0c8", "right-1": ON_MARKING,
                    "right-2": "#b8860b"}
    fig, axes = plt.subplots(3, 2, figsize=(13.0, 8.6), dpi=DPI, sharex=True,
                             gridspec_kw=dict(height_ratios=[1.5, 1, 1]))
    for col, lanes in enumerate((3, 2)):
        track, rows = overtake(lanes)
        t = np.array([r[0] for r in rows])
        d = np.array([r[1] for r in rows])
        steer = np.array([r[2] for r in rows])
        speed = np.array([r[3] for r in rows])
        gap = np.array([r[4] for r in rows])
        states = [r[5] for r in rows]
        ax = axes[0, col]
        for j, x in enumerate(track.markings):
            ax.axhline(x, color="black", lw=1.5 if j in (0, lanes) else 1.0, ls="-" if j in (0, lanes) else "--")
        for k, x in enumerate(track.lane_centres):
            ax.axhline(x, color=GREY, lw=0.7, ls=":")
            ax.text(t[-1] + 0.3, x, f"lane {k}", fontsize=9, va="center")
        for name, colr in state_colour.items():
            m = np.array([st == name for st in states])
            if m.any():
                ax.scatter(t[m], d[m], s=7, color=colr, label=name, zorder=3)
        ax.set_ylabel("d [m] (left up)", fontsize=10)
        ax.set_ylim(track.markings[-1] - 3.2, track.markings[0] + 0.8)
        ax.legend(title="controller state", fontsize=9, title_fontsize=9, loc="lower center", markerscale=2.5,
                  ncol=5, columnspacing=1.0, handletextpad=0.3)
        ax.set_title(f"{lanes} lanes: host at 18 m/s in lane 1, a car at 8 m/s 40 m ahead", fontsize=11)
        axes[1, col].plot(t, steer, color=HOST, lw=1.5)
        axes[1, col].axhline(0, color="black", lw=0.7)
        axes[1, col].set_ylabel("steer (+ left)", fontsize=10)
        axes[2, col].plot(t, speed, color=IN_LANE, lw=1.8, label="host speed [m/s]")
        axes[2, col].plot(t, np.where(gap > -30, gap, np.nan), color=ON_MARKING, lw=1.5,
                          label="gap to the slow car [m] (negative: passed)")
        axes[2, col].axhline(0, color="black", lw=0.7)
        axes[2, col].set_ylim(-32, 45)
        axes[2, col].legend(fontsize=9, loc="upper right")
        axes[2, col].set_xlabel("time [s]", fontsize=10)
        for ax in axes[:, col]:
            ax.grid(alpha=0.3)
            ax.set_xlim(0, t[-1] + 1.6)
    fig.suptitle("Closed loop: ChenController on the exact indicators, driving the host car's kinematic model at 10 Hz",
                 fontsize=12)
    fig.tight_layout()
    save(fig, "controller-overtake.png")


def draw_state_machine() -> None:
    p = ChenParams()
    fig, ax = plt.subplots(figsize=(13.0, 6.6), dpi=DPI)
    ax.set_xlim(0, 13)
    ax.set_ylim(0, 6.6)
    ax.axis("off")
    boxes = {  # name: (centre x, centre y, width, height, title, body)
        "keep": (6.5, 5.05, 4.6, 1.2, "keep (rule 4: lane keeping)",
                 f"in-lane estimate trusted: target (ML + MR) / 2, coe {p.coe_keep:g}\n"
                 f"({p.coe_keep_near_marking:g} if toMarking_M < {p.near_marking:g}); "
                 f"else the lane beside the marking, coe {p.coe_on_marking:g}"),
        "left-1": (2.0, 3.0, 3.7, 1.25, "left-1 (phase 1)", f"target (LL + ML) / 2, coe {p.coe_change:g}\n"
                   f"averaged with (L + M) / 2 when\ntoMarking_L > -{p.change_marking_outer:g} "
                   f"and toMarking_M < {p.change_marking_m:g}"),
        "left-2": (2.0, 0.8, 3.0, 0.75, "left-2 (phase 2)", f"target (L + M) / 2, coe {p.coe_change_phase_2:g}"),
        "right-1": (11.0, 3.0, 3.7, 1.25, "right-1 (phase 1)", f"target (RR + MR) / 2, coe {p.coe_change:g}\n"
                    f"averaged with (R + M) / 2 when\ntoMarking_R < {p.change_marking_outer:g} "
                    f"and toMarking_M > -{p.change_marking_m:g}"),
        "right-2": (11.0, 0.8, 3.0, 0.75, "right-2 (phase 2)", f"target (R + M) / 2, coe {p.coe_change_phase_2:g}"),
    }
    for name, (x, y, w, h, title, body) in boxes.items():
        col = "black" if name == "keep" else IN_LANE if name.startswith("left") else ON_MARKING
        ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h, boxstyle="round,pad=0.08", fc="white", ec=col,
                                    lw=2))
        ax.text(x, y + h / 2 - 0.08, title, ha="center", va="top", fontsize=11, fontweight="bold", color=col)
        ax.text(x, y + h / 2 - 0.4, body, ha="center", va="top", fontsize=9.5)

    def arrow(a, b, text, tx, ty, col, rad=0.0, ha="center"):
        ax.add_patch(FancyArrowPatch(a, b, arrowstyle="-|>", mutation_scale=16, lw=1.8, color=col,
                                     connectionstyle=f"arc3,rad={rad}", shrinkA=2, shrinkB=2))
        ax.text(tx, ty, text, ha=ha, va="center", fontsize=9.5, color=col,
                bbox=dict(boxstyle="round,pad=0.2", fc="white", ec="none", alpha=0.9))

    arrow((4.15, 5.0), (2.3, 3.7), "go left", 2.9, 4.65, IN_LANE, rad=0.2)
    arrow((8.85, 5.0), (10.7, 3.7), "go right", 10.1, 4.65, ON_MARKING, rad=-0.2)
    lost = f"in-lane estimate lost:\n-ML + MR >= {p.in_lane_span:g}"
    arrow((1.4, 2.3), (1.4, 1.25), lost, 1.55, 1.78, IN_LANE, ha="left")
    arrow((11.6, 2.3), (11.6, 1.25), lost, 11.45, 1.78, ON_MARKING, ha="right")
    arrow((3.6, 0.85), (5.4, 4.35), f"on-marking test fails:\ntoMarking_L <= -{p.change_marking_outer:g} or\n"
          f"toMarking_M >= {p.change_marking_m:g}\n(lane keeping at once)", 4.8, 2.85, IN_LANE, ha="left")
    arrow((9.4, 0.85), (7.6, 4.35), f"on-marking test fails:\ntoMarking_R >= {p.change_marking_outer:g} or\n"
          f"toMarking_M <= -{p.change_marking_m:g}\n(lane keeping at once)", 8.2, 2.85, ON_MARKING, ha="right")
    start = (f"A change starts from keep by\nrule 2 (overtake): dist_MM < {p.follow_gap:g}, the lane exists\n"
             f"(toMarking_LL > {p.left_lane_exists:g} / toMarking_RR < {p.right_lane_exists:g}), it has been clear\n"
             f"for > {p.timer_set} frames, and the steer_trend test;\nrule 3 (lane preference); or the expert's "
             "forced change")
    ax.text(6.5, 0.75, start, ha="center", va="center", fontsize=9.5,
            bbox=dict(boxstyle="round,pad=0.35", fc="#f4f4f4", ec=GREY))
    ax.text(6.5, 6.5, "The lane-change state machine (rules 2, 3 and 5); "
            "coe = coe_steer, the steering divisor of rule 6", ha="center", va="top", fontsize=12, fontweight="bold")
    fig.tight_layout()
    save(fig, "controller-states.png")


# --- the cars beside and behind (the extended label set) -------------------------------------------------------------
@dataclass
class RearScene:
    title: str
    lanes: int
    d: float                 # [m] host car's lateral offset
    speed: float             # [m/s] host car's speed
    cars: tuple              # ((gap along s [m] centre to centre, d [m], length [m], speed [m/s]), ...)


REAR_SCENES = [
    RearScene("3 lanes, host in the centre lane", 3, 0.2, 15.0,
              ((-1.5, 4.1, 4.4, 16.0), (-26.0, 3.9, 4.6, 24.0), (-19.0, -4.0, 4.9, 21.0), (9.0, -4.1, 4.1, 12.0),
               (-16.0, 0.1, 4.6, 15.0))),
    RearScene("2 lanes, host in the left lane", 2, 2.1, 20.0, ((-110.0, -2.0, 4.6, 28.0), (8.0, -2.0, 4.4, 18.0))),
]


def draw_rear_panel(ax, s: RearScene) -> dict[str, float]:
    track = demo_track(s.lanes)
    cars = np.asarray(s.cars, dtype=float).reshape(-1, 4)
    v = dict(zip(REAR, (float(x) for x in rear_indicators(
        track, EGO_S, s.d, HOST_LENGTH, s.speed, EGO_S + cars[:, 0], cars[:, 1], cars[:, 2], cars[:, 3]))))
    half = track.half_width + VERGE_WIDTH + 0.4
    y0, y1 = -118.0, 14.0
    draw_road(ax, track, y0, y1)
    ax.axhspan(-HOST_LENGTH / 2, HOST_LENGTH / 2, color=HOST, alpha=0.12, zorder=1)
    ax.axhline(-HOST_LENGTH / 2, color=HOST, lw=0.8, ls="--", zorder=2)
    ax.axhline(-HOST_LENGTH / 2 - REAR_RANGE, color="black", lw=1.0, ls=(0, (5, 3)), zorder=2)
    ax.text(half - 0.2, -HOST_LENGTH / 2 - REAR_RANGE + 0.8, f"{REAR_RANGE:.0f} m behind the rear bumper",
            fontsize=8.5, ha="left", va="bottom", zorder=7, bbox=dict(boxstyle="round,pad=0.1", fc="white",
                                                                      ec="none", alpha=0.8))
    for ds, cd, length, speed in cars:
        ax.add_patch(Rectangle((cd - 0.95, ds - length / 2), 1.9, length, fc=OTHER, ec="black", lw=1, zorder=4))
        ax.text(cd + 1.15, ds, f"{speed:.0f} m/s", fontsize=8.5, ha="right", va="center", zorder=7)
    ax.add_patch(Rectangle((s.d - 0.95, -HOST_LENGTH / 2), 1.9, HOST_LENGTH, fc=HOST, ec="black", lw=1.2, zorder=8))
    ax.text(s.d - 1.15, 0.0, f"{s.speed:.0f} m/s", fontsize=8.5, ha="left", va="center", color=HOST, zorder=9,
            bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.85))
    k = track.lane_of(s.d)
    for side, lane, name in ((+1, k - 1, "LB"), (-1, k + 1, "RB")):
        gap, closing = v[f"dist_{name}"], v[f"closing_{name}"]
        if not 0 <= lane < track.lanes:
            ax.text(track.markings[0 if side > 0 else -1] + side * 1.0, -45.0,
                    f"dist_{name} = {gap:.0f}, closing_{name} = {closing:+.0f} (no lane)", color="black", fontsize=9,
                    ha="center", va="center", rotation=90, zorder=7)
            continue
        x = track.lane_centres[lane] - side * 1.35
        if 0 < gap < REAR_RANGE:
            top = -HOST_LENGTH / 2
            ax.add_patch(FancyArrowPatch((x, top), (x, top - max(gap, 0.01)), arrowstyle="<|-|>",
                                         mutation_scale=10, lw=1.8, color=IN_LANE, zorder=6, shrinkA=0, shrinkB=0))
        text = (f"dist_{name} = {gap:.1f} m" + (" (alongside)" if gap == 0 else "") +
                f"\nclosing_{name} = {closing:+.1f} m/s" if gap < REAR_RANGE else
                f"dist_{name} = {gap:.0f}, closing_{name} = {closing:+.0f}\n(no car within {REAR_RANGE:.0f} m)")
        ax.text(x - side * 0.2, -55.0, text, color=IN_LANE, fontsize=9, fontweight="bold", rotation=90,
                ha="center", va="center", zorder=7, bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none",
                                                              alpha=0.85))
    ax.set_xlim(half, -half)
    ax.set_ylim(y0, y1)
    ax.set_xticks(track.lane_centres)
    ax.set_xticklabels([f"lane {j}" for j in range(track.lanes)], fontsize=9)
    ax.set_ylabel("along the centreline from the host's centre [m]", fontsize=9)
    ax.tick_params(axis="y", labelsize=9)
    ax.set_title(s.title, fontsize=11)
    return v


def draw_rear_labels() -> None:
    fig, axes = plt.subplots(1, 3, figsize=(14.0, 8.2), dpi=DPI, gridspec_kw=dict(width_ratios=[1, 0.8, 0.9]))
    values = [draw_rear_panel(ax, s) for ax, s in zip(axes[:2], REAR_SCENES)]
    ax = axes[2]
    ax.axis("off")
    y = 0.98
    for s, v in zip(REAR_SCENES, values):
        ax.text(0.0, y, s.title, fontsize=11, fontweight="bold", va="top", transform=ax.transAxes)
        y -= 0.055
        for name in REAR:
            unit = "m/s" if name.startswith("closing") else "m"
            need = ""
            if name.startswith("dist") and v[name] < REAR_RANGE:
                need = f"  (lookout needs {safe_gap(v['closing_' + name[-2:]], s.speed):.1f} m)"
            ax.text(0.0, y, f"{name:<11}{v[name]:+7.2f} {unit}{need}", family="monospace", fontsize=9.5,
                    va="top", transform=ax.transAxes)
            y -= 0.045
        y -= 0.04
    notes = ["For the lanes left and right of the host's lane",
             "(lanes_left), the nearest car alongside or behind:",
             "bumper-to-bumper gap along the centreline, 0 while",
             "it overlaps the host's length (red band), and its",
             "speed minus the host's. A car wholly ahead is a",
             "dist_LL / dist_RR car, not one of these. No lane,",
             f"or no car within {REAR_RANGE:.0f} m: {REAR_RANGE:.0f} m and 0 m/s.",
             "The car 16 m behind in the host's own lane and",
             "the cars wholly ahead count in no rear label; on",
             "the left of the 3-lane host only the nearest car",
             "counts (the faster one further back does not)."]
    for line in notes:
        ax.text(0.0, y, line, fontsize=9.5, va="top", transform=ax.transAxes)
        y -= 0.04
    fig.suptitle("The cars beside and behind: dist_LB, dist_RB, closing_LB, closing_RB (host red, other cars "
                 "yellow with their speeds; driving direction up; along-track scale compressed)", fontsize=11.5)
    fig.tight_layout()
    save(fig, "affordances-rear.png")


def draw_safe_gap() -> None:
    p = LookoutParams()
    c = np.linspace(-5.0, 25.0, 301)
    fig, ax = plt.subplots(figsize=(10.0, 5.6), dpi=DPI)
    for speed, col in ((8.0, HOST), (14.0, ON_MARKING), (20.0, IN_LANE)):
        t = crossing(speed, p)
        ax.plot(c, [safe_gap(x, speed, p) for x in c], color=col, lw=2.3,
                label=f"host at {speed:g} m/s: crosses in {t:.2f} s; L1 (start) allows {t + p.margin_time:.2f} s")
        ax.plot(c, [safe_gap(x, speed, p, abort=True) for x in c], color=col, lw=1.4, ls="--",
                label=f"host at {speed:g} m/s: L2 (abort) below this, {t:.2f} s")
    ax.axhline(REAR_RANGE, color="black", lw=1, ls=(0, (5, 3)))
    ax.text(24.8, REAR_RANGE + 1, f"rear labels reach {REAR_RANGE:.0f} m", fontsize=10, va="bottom", ha="right")
    ax.set_xlabel("c: closing speed of the car beside or behind in the target lane [m/s] "
                  "(its speed minus the host's, plus what L3 takes off the host)", fontsize=10)
    ax.set_ylabel("rear gap needed [m] (bumper to bumper)", fontsize=10)
    ax.set_title(f"The lookout's safe gap need(c, T) = {p.min_gap:g} + c T + c^2 / {2 * p.follower_decel:g} "
                 "(lookout.safe_gap): a change starts only above\nthe solid curve of the host's speed and is given up "
                 "(until the centre crosses the marking) below the dashed one", fontsize=11)
    ax.set_xlim(c[0], c[-1])
    ax.set_ylim(0, 120)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", fontsize=8.5, bbox_to_anchor=(0.0, 0.8))
    fig.tight_layout()
    save(fig, "controller-safe-gap.png")


def save(fig, name: str) -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / name
    fig.savefig(path, dpi=DPI, facecolor="white")
    plt.close(fig)
    print(f"wrote {path.relative_to(ROOT)} ({path.stat().st_size // 1024} kB)")


def main() -> None:
    for scene in SCENES:
        draw_scene(scene)
    draw_follow_curve()
    draw_steering_curve()
    draw_overtakes()
    draw_state_machine()
    draw_rear_labels()
    draw_safe_gap()


if __name__ == "__main__":
    main()
