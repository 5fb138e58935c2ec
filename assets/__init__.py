"""Small, versioned assets: the track presets (car models are made with trimesh, see sim/highway/car_models.py)."""
from pathlib import Path

ASSETS_DIR = Path(__file__).resolve().parent
TRACKS_DIR = ASSETS_DIR / "tracks"
