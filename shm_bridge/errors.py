"""The bridge's exceptions. Their messages are single lines meant for a user (the CLI prints them on stderr)."""
from __future__ import annotations


class BridgeError(RuntimeError):
    """Anything that stops the bridge: a missing segment, a refused attach, a timeout, a dead peer."""


class PeerGone(BridgeError):
    """The other process died, stopped responding, or left the run.

    pid: the peer's process id (0 when unknown); orderly: True when it detached or closed on purpose;
    finished: True when a driver ended the run in order (DriverEndpoint.finish): a success, not a failure.
    """

    def __init__(self, message: str, pid: int = 0, orderly: bool = False, finished: bool = False):
        super().__init__(message)
        self.pid = pid
        self.orderly = orderly
        self.finished = finished


class ProtocolMismatch(BridgeError):
    """The segment is not a bridge segment, or speaks another protocol version or layout."""


class Refused(BridgeError):
    """What was asked cannot be done with this segment: the name is taken, another driver is attached, the file
    belongs to another user, is a symbolic link or not a regular file. The user's to fix (exit status 2)."""


class BridgeTimeout(BridgeError, TimeoutError):
    """A wait with a timeout ran out (no driver attached, no frame, no action)."""


class BadName(BridgeError, ValueError):
    """A shared-memory name that is not a plain file name (a usage error)."""
