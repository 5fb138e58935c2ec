"""The sidewalk world's one-line input error (drivestudio/errors.py reports it: one line, exit status 2)."""

from core.inputs import InputError


class PathError(InputError):
    """A path, obstacle file or world option that cannot be used: a path that does not close, a width out of
    range, a file that does not parse, an unknown mode, an obstacle that blocks the path."""
