"""Errors of the world that are the user's to fix (bad options, missing drivers), reported in one line."""


class RendererError(RuntimeError):
    """The requested renderer cannot run here."""


class TrafficError(RuntimeError):
    """SUMO traffic cannot be set up or run: unusable track, failed start, bad car count."""
