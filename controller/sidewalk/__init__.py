"""The sidewalk world's drivers and rules, on its truth record alone (shm_bridge/worlds/sidewalk.py): the experts
of the three behavioural modes, a deliberately poor driver, the correction rule of correctional operation and
the closed-loop metrics. Depends only on numpy and the declaration."""
from .correction import CorrectionParams, CorrectionRule
from .experts import ExpertParams, SidewalkExpert
from .metrics import SidewalkMetrics
from .poor import PoorDriver

__all__ = ["CorrectionParams", "CorrectionRule", "ExpertParams", "SidewalkExpert", "SidewalkMetrics", "PoorDriver"]
