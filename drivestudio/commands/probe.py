"""drivestudio probe SCENARIO.json: the 14 ground-truth indicators of a scenario as one JSON object."""
from __future__ import annotations

import json

from core.worlds.highway import indicators_to_dict


def register(sub) -> None:
    p = sub.add_parser("probe", help="print the ground-truth indicators of a scenario as JSON",
                       description="Print the 14 DeepDriving indicators (angle, toMarking_LL, ..., dist_R, fast) "
                                   "of a scenario file as one JSON object. See docs/scenarios.md.")
    p.add_argument("scenario", help="scenario JSON file")
    p.add_argument("--lanes", type=int, help="override the track's lane count")
    p.add_argument("--all", action="store_true",
                   help="also print lanes_left, lanes, speed, the systems' activity and the poses")
    p.set_defaults(func=run)


def run(args) -> int:
    # lazy: the highway's simulator imports trimesh (0.3 s), which `drivestudio --help` need not pay
    from sim.highway.scenario import load_scenario
    from sim.highway.world import World, WorldConfig  # lazy: the highway simulator (trimesh, PIL), only when it runs

    scenario = load_scenario(args.scenario, lanes=args.lanes)
    with World(WorldConfig(render=False, cars=0), scenario=scenario) as world:
        truth = world.observe(render=False).truth
    out = truth.as_dict() if args.all else indicators_to_dict(truth.indicators)
    print(json.dumps(out))
    return 0
