"""Shared-memory transport between the world and a driver (the TORCS/Caffe arrangement); nothing else.

Modules (import them directly; this package file imports nothing):
  layout      the binary layout of protocol version 2: the one owner of every offset; `python -m shm_bridge.layout`
              prints the C declarations
  endpoints   WorldEndpoint (creates /dev/shm/NAME, publishes frames, reads actions) and DriverEndpoint
              (attaches, takes frames, sends actions); FrameMsg, ActionMsg; lock-step and free-running modes
  errors      BridgeError, PeerGone, ProtocolMismatch, Refused, BadName, BridgeTimeout
  segment     the /dev/shm file (0600, O_EXCL, inode-checked unlink)
  futex       FUTEX_WAIT / FUTEX_WAKE on words of the segment, through ctypes

What a world declares (its cameras, truth record and action, which the header carries) is core/declaration.py's;
docs/shm-protocol.md describes the protocol byte by byte for drivers written in other languages.
"""
