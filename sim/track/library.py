"""Where tracks come from: a JSON object, a preset (assets/tracks/), `procedural:SEED`, or a track file.

The file format and its checks are sim/track/trackfile.py's; procedural tracks are sim/track/procedural.py's;
this module sits above both.
"""
from __future__ import annotations

from pathlib import Path

from assets import TRACKS_DIR
from core.inputs import read_json, show, show_path
from sim.track.procedural import procedural_spec
from sim.track.track import Track
from sim.track.trackfile import MAX_PROCEDURAL_SEED, TrackError, track_from_spec


def preset_names() -> list[str]:
    return sorted(p.stem for p in TRACKS_DIR.glob("*.json"))


def _in_file(path, loader):
    """Run `loader` on a track that came from `path`, naming the file in what it refuses."""
    try:
        return loader()
    except TrackError as e:
        raise TrackError(f"{show_path(path)}: {e}") from None


def load_track(ref, lanes: int | None = None, lane_width: float | None = None) -> Track:
    """A track from a JSON object, a preset name, 'procedural:SEED', or a path to a track file."""
    if isinstance(ref, dict):
        return track_from_spec(ref, lanes, lane_width)
    if not isinstance(ref, (str, Path)):
        raise TrackError(f"a track is an object, a preset name or a file path, got {show(ref)}")
    ref = str(ref)
    if ref.startswith("procedural:"):
        seed_text = ref.split(":", 1)[1]
        if (not (seed_text.isascii() and seed_text.isdigit()) or len(seed_text) > 19
                or int(seed_text) > MAX_PROCEDURAL_SEED):
            raise TrackError(f"{show(ref)}: the seed of a procedural track must be an integer from 0 to "
                             f"{MAX_PROCEDURAL_SEED}")
        return track_from_spec(procedural_spec(int(seed_text)), lanes, lane_width)
    if "/" not in ref and not ref.endswith(".json"):
        names = preset_names()
        if ref not in names:  # looked up among the presets, never as a file name (it may be anything)
            raise TrackError(f"unknown track preset {show(ref)} (presets: {', '.join(names)}; "
                             f"or give a .json file or procedural:SEED)")
        return track_from_spec(read_json(TRACKS_DIR / f"{ref}.json", "track", error=TrackError), lanes, lane_width)
    data = read_json(Path(ref), "track", error=TrackError)
    return _in_file(ref, lambda: track_from_spec(data, lanes, lane_width))
