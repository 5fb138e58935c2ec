"""Track geometry (the one owner of it) and the track file format."""
from sim.track.library import load_track, preset_names
from sim.track.segments import Arc, Segment, Straight, wrap_angle
from sim.track.track import VERGE_WIDTH, Track
from sim.track.trackfile import MAX_LANES, TrackError, track_from_spec, write_track

__all__ = ["Arc", "Segment", "Straight", "wrap_angle", "Track", "VERGE_WIDTH", "MAX_LANES", "TrackError",
           "load_track", "preset_names", "track_from_spec", "write_track"]
