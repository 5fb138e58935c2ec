"""Small, versioned assets: track files, car meshes, SUMO templates."""
from pathlib import Path

ASSETS_DIR = Path(__file__).resolve().parent
TRACKS_DIR = ASSETS_DIR / "tracks"
CARS_DIR = ASSETS_DIR / "cars"
