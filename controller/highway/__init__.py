"""The highway's drivers and measures, on DeepDriving's indicators (core/worlds/highway.py): the Chen controller,
the data-collection expert that perturbs it, and the closed-loop metrics. Depends only on numpy and the
declaration."""
from controller.highway.chen import ChenController, ChenParams

__all__ = ["ChenController", "ChenParams"]
