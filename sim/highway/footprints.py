"""The car models' names and footprints, light to import: what a scenario file names and checks before any mesh
is built (sim/highway/car_models.py builds the meshes on these footprints; SUMO's vehicle types share them)."""
from __future__ import annotations

# name: (length [m], width [m]), in car_models()'s order (a car's model is an index into it)
FOOTPRINTS: dict[str, tuple[float, float]] = {
    "sedan": (4.6, 1.82),
    "hatchback": (4.1, 1.76),
    "suv": (4.7, 1.92),
    "van": (4.9, 1.98),
    "coupe": (4.4, 1.86),
}
MODEL_NAMES = tuple(FOOTPRINTS)
