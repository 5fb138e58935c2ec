"""drivestudio ppo --minutes M --out MODEL.zip: the highway's reinforcement-learning baseline, PPO on the
affordance observation (drivestudio/worlds/highway/rl_train.py, docs/gymnasium.md); the saved model is a row of
`drivestudio benchmark --model`."""
from __future__ import annotations

from core.files import check_output
from drivestudio.commands.numbers import count, positive, seed
from drivestudio.errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("ppo", help="train the PPO baseline on the highway's affordance observation",
                       description="Train PPO (Stable-Baselines3, the optional `rl` extra) on the highway's "
                                   "affordance observation and its reward, on generate's training tracks; the saved "
                                   ".zip drives in `drivestudio benchmark --model` (docs/gymnasium.md).")
    p.add_argument("--minutes", type=positive(24 * 60.0), default=18.0, help="wall-time budget (default 18)")
    p.add_argument("--steps", type=count(1, 10**9), default=10_000_000,
                   help="environment steps at most (default: no cap)")
    p.add_argument("--out", default="runs/ppo-highway.zip", help="the saved model (default runs/ppo-highway.zip)")
    p.add_argument("--seed", type=seed(), default=0, help="seed of the tracks and the policy (default 0)")
    p.set_defaults(func=run)


def run(args) -> int:
    out = check_output(args.out, (".zip",), "model")
    try:
        import stable_baselines3  # noqa: F401  the optional dependency, checked before anything starts
    except ImportError:
        raise UsageError("Stable-Baselines3 is not installed (pip install 'drivestudio[rl]')") from None
    from drivestudio.worlds.highway.rl_train import train  # lazy: gymnasium, torch and the world
    print(train(args.minutes, args.steps, out, args.seed))
    return 0
