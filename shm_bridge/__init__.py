"""Shared-memory transport between the world and a driver, and the message vocabulary every package shares.

Modules (import them directly; this package file imports nothing):
  vocabulary  indicator names and order, inactive values, normalisation, the Action (the shared vocabulary)
  layout      the binary layout of protocol version 1 and the truth record (pack_truth / unpack_truth); the one
              owner of every offset; `python -m shm_bridge.layout` prints the C declarations
  endpoints   WorldEndpoint (creates /dev/shm/NAME, publishes frames, reads actions) and DriverEndpoint
              (attaches, takes frames, sends actions); FrameMsg, ActionMsg; lock-step and free-running modes
  errors      BridgeError, PeerGone, ProtocolMismatch, BridgeTimeout
  signals     exit_on_sigterm(): SIGTERM/SIGHUP unwind like Ctrl-C, so the segment is removed
  segment     the /dev/shm file (0600, O_EXCL, inode-checked unlink) and process liveness
  futex       FUTEX_WAIT / FUTEX_WAKE on words of the segment, through ctypes

docs/shm-protocol.md describes the protocol byte by byte for drivers written in other languages.
"""
