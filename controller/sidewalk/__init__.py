"""The sidewalk world's drivers and rules, on its truth record alone (core/worlds/sidewalk.py): the experts
of the three behavioural modes, a deliberately poor driver, the correction rule of correctional operation and
the closed-loop metrics. Depends only on numpy and the declaration."""
from controller.sidewalk.correction import CorrectionParams, CorrectionRule
from controller.sidewalk.experts import ExpertParams, SidewalkExpert
from controller.sidewalk.metrics import SidewalkMetrics
from controller.sidewalk.poor import PoorDriver

__all__ = ["CorrectionParams", "CorrectionRule", "ExpertParams", "SidewalkExpert", "SidewalkMetrics", "PoorDriver"]
