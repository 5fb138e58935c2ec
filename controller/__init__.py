"""Controllers and experts, one package per world, on the world's truth record or estimates alone: the Chen
controller, its data-collection expert and the closed-loop metrics of the highway (controller/highway/); the
experts, the poor driver, the correction rule and the metrics of the sidewalk (controller/sidewalk/). Depends only
on numpy and the worlds' declarations (core/worlds/)."""
