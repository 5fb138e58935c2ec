"""Colours as PyBullet's TinyRenderer holds and lights them, which both fast renderers reproduce."""
from __future__ import annotations

import numpy as np


def base_colour(rgb) -> np.ndarray:
    """A colour (0-1, float32 as PyBullet passes it) as TinyRenderer holds it before lighting: 0-255, cut to whole
    levels (the white of an untextured mesh times the colour, stored in a byte)."""
    return np.floor(np.float32(255.0) * np.asarray(rgb, dtype=np.float32)).astype(np.float32)
