"""The named conditions a world is drawn in (docs/conditions.md): the vocabulary both worlds, the command line, the
Gymnasium keyword arguments and the datasets share.

`seeded` is the look each world always had, drawn from the seed (the highway: sunny or overcast; the sidewalk: a time
of day); it is every world's default, so frames made before conditions existed stay what they were. A world's
`condition` setting names one condition or a mix (`clear,fog,night`): each seed draws one of the mix (`pick`), so an
episode, a route or a reset is drawn in one condition throughout.
"""
from __future__ import annotations

import numpy as np

from core.declaration import Column

SEEDED = "seeded"
CONDITIONS = (SEEDED, "clear", "overcast", "low_sun", "night", "fog", "rain")

# recorded per frame by a world drawn in a named condition; metadata like `track`, never a regression target
CONDITION_COLUMN = Column("condition", "str", "the named condition the frame was drawn in (docs/conditions.md)")

_PICK = 0xC0D   # the stream of the draw of a mix's condition, apart from every other draw of a seed


def names(text: str) -> tuple[str, ...]:
    """The conditions of a setting's text, `name` or `name,name,...` (checked by the setting's choices)."""
    return tuple(n.strip() for n in str(text).split(","))


def pick(text: str, seed: int) -> str:
    """The condition a seed draws from the mix `text` (one name: that one)."""
    mix = names(text)
    if len(mix) == 1:
        return mix[0]
    return mix[int(np.random.default_rng([int(seed), _PICK]).integers(len(mix)))]


def parameter_stream(name: str, seed: int) -> np.random.Generator:
    """The random stream a condition's parameters (sun, visibility, rain) are drawn from for a seed."""
    return np.random.default_rng([int(seed), _PICK, CONDITIONS.index(name)])
