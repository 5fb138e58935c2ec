"""The sidewalk world's declaration: a 1/10-scale car with a stereo camera on sidewalks and park paths, driven in
three behavioural modes (Chowdhuri, Pankaj and Zipser, MultiNet, 2017). docs/sidewalk.md describes the world.

Steering and motor are in [0, 1] as on MultiNet's cars: steer 0.5 straight, 1 full right, 0 full left; motor 0.5
stop, 1 full speed forward (about 9 m/s), 0 full reverse. A data moment is the stereo pair now and one step
(33 ms) earlier with the next 10 steering and 10 motor values.
"""
from __future__ import annotations

from shm_bridge.declaration import Camera, Column, Control, Label, Moment, Quantity, WorldDeclaration

MODES = ("direct", "follow", "furtive")                 # behavioural modes
OPERATIONS = ("expert", "autonomous", "correctional")   # operation modes
STEP = 1 / 30                                          # [s] the ZED camera's 30 Hz
CAMERA = (188, 336)      # (rows, columns) each camera renders: 2x2-averaged to the network's 94 x 168
HORIZON = 10             # future steps a data moment's targets cover (330 ms ahead at the 10th)

SIDEWALK = WorldDeclaration(
    name="sidewalk",
    title="1/10-scale car with a stereo camera on sidewalks and park paths (MultiNet)",
    dt=STEP,
    cameras=(Camera("left", *CAMERA), Camera("right", *CAMERA)),
    labels=(Label("steer", "0..1", "steering: 0 full left, 0.5 straight, 1 full right"),
            Label("motor", "0..1", "motor: 0 full reverse, 0.5 stop, 1 full speed forward")),
    truth=(
        Quantity("steer", "0..1", "the applied steering command", "f32"),
        Quantity("motor", "0..1", "the applied motor command", "f32"),
        Quantity("behaviour", "index", "behavioural mode: 0 direct, 1 follow, 2 furtive", "i8"),
        Quantity("operation", "index", "operation mode: 0 expert, 1 autonomous, 2 correctional", "i8"),
        Quantity("correcting", "0/1", "1: the expert has taken over from the autonomous driver", "bool"),
        Quantity("speed", "m/s", "car's speed (negative in reverse)", "f32"),
        Quantity("x", "m", "car's position, world frame", "f64"),
        Quantity("y", "m", "car's position, world frame", "f64"),
        Quantity("yaw", "rad", "car's heading, counter-clockwise", "f64"),
        Quantity("s", "m", "arc length along the path's centreline", "f64"),
        Quantity("d", "m", "lateral offset from the path's centreline, positive left", "f64"),
        Quantity("heading", "rad", "car's yaw minus the path tangent, counter-clockwise", "f32"),
        Quantity("path_width", "m", "width of the path here", "f32"),
        Quantity("border_left", "m", "distance from the car's left side to a bordering bush on the left "
                                     "(capped at 5; 5 where there is none)", "f32"),
        Quantity("border_right", "m", "distance from the car's right side to a bordering bush on the right "
                                      "(capped at 5)", "f32"),
        Quantity("obstacle_gap", "m", "along-path distance to the nearest obstacle ahead on the path "
                                      "(capped at 30)", "f32"),
        Quantity("obstacle_d", "m", "lateral offset of that obstacle (0 when none)", "f32"),
        Quantity("lead_gap", "m", "along-path distance to the lead car (follow mode; 30 when none)", "f32"),
        Quantity("obstacle_near", "0/1", "1: an obstacle lies within 3 m ahead on the path", "bool"),
        Quantity("collision", "0/1", "1: the car touches an obstacle, a bush or the lead car", "bool"),
        Quantity("off_path", "0/1", "1: the car's centre is beyond the path's edge", "bool"),
    ),
    action=(Control("steer", "0..1", "0 full left, 0.5 straight, 1 full right", 0.0, 1.0, 0.5),
            Control("motor", "0..1", "0 full reverse, 0.5 stop, 1 full speed forward (about 9 m/s)", 0.0, 1.0, 0.5)),
    columns=(Column("path", "str", "path reference (preset, file or procedural:SEED)"),),
    modes=MODES,
    mode_field="behaviour",
    moment=Moment(instants=(-1, 0), horizon=HORIZON),
    targets=("steer", "motor"),
)
