"""Controllers and experts: the Chen controller (highway), its data-collection expert, closed-loop metrics. Depends
only on numpy and the worlds' declarations (shm_bridge/worlds/)."""
from .chen import ChenController, ChenParams

__all__ = ["ChenController", "ChenParams"]
