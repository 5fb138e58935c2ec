"""The sidewalk world's declaration: a 1/10-scale car with a stereo camera on sidewalks and park paths, driven in
three behavioural modes (Chowdhuri, Pankaj and Zipser, MultiNet, 2017). docs/sidewalk.md describes the world.

Steering and motor are in [0, 1] as on MultiNet's cars: steer 0.5 straight, 1 full right, 0 full left; motor 0.5
stop, 1 full speed forward (about 9 m/s), 0 full reverse. A data moment is the stereo pair now and one step
(33 ms) earlier with the next 10 steering and 10 motor values.

The record of step t holds the command the car is under at t (chosen on the frame of step t - 1) and the
operation mode that chose it; so the targets of a moment at t (the labels of steps t+1 .. t+10) are the commands
chosen on the frames of steps t .. t+9.
"""
from __future__ import annotations

from core.declaration import Camera, Column, Control, Label, Moment, Quantity, WorldDeclaration

MODES = ("direct", "follow", "furtive")                 # behavioural modes
OPERATIONS = ("expert", "autonomous", "correctional")   # operation modes
RULES = ("safety", "strict")                            # correction rules (controller/sidewalk/correction.py)
STEP = 1 / 30                                          # [s] the ZED camera's 30 Hz
CAMERA = (188, 336)      # (rows, columns) each camera renders: 2x2-averaged to the network's 94 x 168
HORIZON = 10             # future steps a data moment's targets cover (330 ms ahead at the 10th)

# the car, as the world simulates it (sim/sidewalk/car.py) and the experts steer it (controller/sidewalk/)
CAR_LENGTH = 0.45        # [m] body
CAR_WIDTH = 0.20         # [m]
WHEELBASE = 0.27         # [m]
REAR_TO_CG = 0.135       # [m] rear axle to the body's centre, the reference point of the pose
STEER_LOCK_RAD = 0.40    # [rad] front-wheel angle at steer 0 (full left) or 1 (full right)
TOP_SPEED = 9.0          # [m/s] at motor 1

SIDEWALK = WorldDeclaration(
    name="sidewalk",
    title="1/10-scale car with a stereo camera on sidewalks and park paths (MultiNet)",
    dt=STEP,
    cameras=(Camera("left", *CAMERA), Camera("right", *CAMERA)),
    labels=(Label("steer", "0..1", "steering: 0 full left, 0.5 straight, 1 full right"),
            Label("motor", "0..1", "motor: 0 full reverse, 0.5 stop, 1 full speed forward")),
    truth=(
        Quantity("steer", "0..1", "the steering command the car is under (the last one applied)", "f32"),
        Quantity("motor", "0..1", "the motor command the car is under (the last one applied)", "f32"),
        Quantity("behaviour", "index", "behavioural mode: 0 direct, 1 follow, 2 furtive", "i8"),
        Quantity("operation", "index", "operation mode of that command: 0 expert, 1 autonomous, 2 correctional",
                 "i8"),
        Quantity("correcting", "0/1", "1: that command was the expert's, taking over from the autonomous driver",
                 "bool"),
        Quantity("speed", "m/s", "car's speed (negative in reverse)", "f32"),
        Quantity("x", "m", "car's position (centre of its body), world frame", "f64"),
        Quantity("y", "m", "car's position, world frame", "f64"),
        Quantity("yaw", "rad", "car's heading, counter-clockwise from +x", "f64"),
        Quantity("s", "m", "arc length along the path's centreline", "f64"),
        Quantity("d", "m", "lateral offset from the path's centreline, positive left", "f64"),
        Quantity("heading", "rad", "car's yaw minus the path tangent, counter-clockwise", "f32"),
        Quantity("path_width", "m", "width of the path", "f32"),
        Quantity("curvature", "1/m", "the path's curvature at s, positive turning left", "f32"),
        Quantity("curvature_ahead", "1/m", "the path's mean curvature over the next 1.5 m: its turn from s to "
                                           "s + 1.5 m, divided by 1.5 m", "f32"),
        Quantity("border_left", "m", "clearance from the car body's leftmost corner to the face of the hedge or "
                                     "bushes bordering the path on the left (5 where there is none; <= 0: touching)",
                 "f32"),
        Quantity("border_right", "m", "the same on the right", "f32"),
        Quantity("obstacle_gap", "m", "along the path, from the car's front to the near edge of the next obstacle "
                                      "not yet passed (negative while alongside; 30 when none within 30 m)", "f32"),
        Quantity("obstacle_d", "m", "lateral offset of that obstacle's centre (0 when none)", "f32"),
        Quantity("obstacle_width", "m", "that obstacle's extent across the path (0 when none)", "f32"),
        Quantity("lead_gap", "m", "along the path, from the car's front to the lead car's rear (follow mode; 30 "
                                  "when there is no lead car)", "f32"),
        Quantity("lead_d", "m", "lead car's lateral offset (0 when none)", "f32"),
        Quantity("lead_speed", "m/s", "lead car's speed (0 when none)", "f32"),
        Quantity("obstacle_near", "0/1", "1: obstacle_gap < 3 m (an obstacle within 3 m ahead, or alongside)",
                 "bool"),
        Quantity("collision", "0/1", "1: the car's body touches an obstacle, a tree, a border or the lead car",
                 "bool"),
        Quantity("off_path", "0/1", "1: the car's centre is beyond the path's edge", "bool"),
    ),
    action=(Control("steer", "0..1", "0 full left, 0.5 straight, 1 full right", 0.0, 1.0, 0.5),
            Control("motor", "0..1", "0 full reverse, 0.5 stop, 1 full speed forward (about 9 m/s)", 0.0, 1.0, 0.5)),
    columns=(Column("path", "str", "path reference (preset, file or procedural:SEED)"),),
    modes=MODES,
    mode_field="behaviour",
    moment=Moment(instants=(-1, 0), horizon=HORIZON),
    targets=("steer", "motor"),
    # what the car could sense of itself and its surroundings (docs/gymnasium.md); not its map position (x, y, yaw,
    # s), the recording's bookkeeping (operation, correcting) nor the outcomes the reward scores (collision, off_path)
    observable=("steer", "motor", "behaviour", "speed", "d", "heading", "path_width", "curvature", "curvature_ahead",
                "border_left", "border_right", "obstacle_gap", "obstacle_d", "obstacle_width", "lead_gap", "lead_d",
                "lead_speed", "obstacle_near"),
)
