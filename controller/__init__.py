"""Controllers that drive from the affordance indicators; depends only on the shared vocabulary."""
from .chen import ChenController, ChenParams

__all__ = ["ChenController", "ChenParams"]
