"""A POSIX shared-memory segment (/dev/shm/NAME) mapped into this process, without multiprocessing's tracker.

Creation is O_CREAT | O_EXCL | O_NOFOLLOW with mode 0600, so the segment is private to the user and a name that
is already taken is never silently reused. Removal checks the inode first, so a process never unlinks a newer
segment that someone else created under the same name. The file under /dev/shm is the same object that C's
shm_open("/NAME", ...) opens.
"""
from __future__ import annotations

import errno
import mmap
import os
import re
import stat

import numpy as np

from shm_bridge.errors import BadName, Refused

SHM_DIR = "/dev/shm"
MODE = 0o600
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9._-]{0,199}")


def validate_name(name: str) -> str:
    """The segment name without a leading '/', or BridgeError for a name that is not a plain file name."""
    if not isinstance(name, str):
        raise BadName(f"shared-memory name must be a string, got {type(name).__name__}")
    bare = name[1:] if name.startswith("/") else name
    if not _NAME.fullmatch(bare):
        raise BadName(f"bad shared-memory name {name!r}: use 1-200 characters from A-Z a-z 0-9 . _ - "
                          "(not starting with '.' or '-')")
    return bare


def shm_path(name: str) -> str:
    return os.path.join(SHM_DIR, validate_name(name))


class Segment:
    """An open, mapped segment: fd, mapping, whole-mapping views and the identity (dev, ino) of its file."""

    def __init__(self, name: str, fd: int, size: int):
        self.name = validate_name(name)
        self.path = shm_path(name)
        self.fd = fd
        st = os.fstat(fd)
        self.dev, self.ino = st.st_dev, st.st_ino
        self.size = size
        self.mm = mmap.mmap(fd, size, mmap.MAP_SHARED, mmap.PROT_READ | mmap.PROT_WRITE)
        self.buf = np.frombuffer(self.mm, dtype=np.uint8)
        self.address = self.buf.ctypes.data
        whole = memoryview(self.mm)
        self.u32 = whole.cast("I")   # native order; layout.check_native_byte_order() makes it little-endian
        self.i32 = whole.cast("i")
        self.u64 = whole.cast("Q")
        whole.release()
        self._closed = False

    # --- creation and opening ----------------------------------------------------------------------------------
    @classmethod
    def create(cls, name: str, size: int) -> Segment:
        """Create /dev/shm/NAME (0600, exclusive) of `size` zero bytes; FileExistsError when the name is taken."""
        path = shm_path(name)
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, MODE)
        try:
            os.fchmod(fd, MODE)   # whatever the umask
            os.ftruncate(fd, size)
            return cls(name, fd, size)
        except BaseException:
            os.close(fd)
            _unlink_quiet(path)
            raise

    @classmethod
    def open(cls, name: str, min_size: int) -> Segment | None:
        """Open an existing segment of at least `min_size` bytes (mapping all of it); None when it does not
        exist or is still shorter (being created). Refused when the file is a symbolic link, not a regular file or
        not the user's own."""
        path = shm_path(name)
        try:
            fd = os.open(path, os.O_RDWR | os.O_NOFOLLOW | os.O_CLOEXEC)
        except FileNotFoundError:
            return None
        except OSError as e:
            if e.errno == errno.ELOOP:
                raise Refused(f"shared memory {name!r} is a symbolic link ({path}); refusing to follow it") from None
            raise Refused(f"cannot open shared memory {name!r}: {e.strerror}") from None
        keep = False
        try:
            st = os.fstat(fd)
            if not stat.S_ISREG(st.st_mode):
                raise Refused(f"shared memory {name!r} is not a regular file")
            if st.st_uid != os.geteuid():
                raise Refused(f"shared memory {name!r} belongs to uid {st.st_uid}, not to this user "
                                  f"(uid {os.geteuid()}); refusing to attach")
            if st.st_size < min_size:
                return None
            segment = cls(name, fd, st.st_size)
            keep = True
            return segment
        finally:
            if not keep:
                os.close(fd)

    # --- identity and removal ------------------------------------------------------------------------------------
    def is_linked(self) -> bool:
        """Whether /dev/shm/NAME still is this segment's file."""
        try:
            st = os.stat(self.path, follow_symlinks=False)
        except FileNotFoundError:
            return False
        return (st.st_dev, st.st_ino) == (self.dev, self.ino)

    def unlink(self) -> bool:
        """Remove /dev/shm/NAME if it still is this segment; True when this call removed it."""
        return unlink_if_same(self.path, self.dev, self.ino)

    def close(self) -> None:
        """Unmap and close the descriptor (the file itself stays unless unlinked)."""
        if self._closed:
            return
        self._closed = True
        for view in (self.u32, self.i32, self.u64):
            view.release()
        self.buf = None  # type: ignore[assignment]  # released: a later use fails loudly
        try:
            self.mm.close()
        except BufferError:
            pass  # a numpy view of the mapping is still referenced; the mapping goes when it is collected
        try:
            os.close(self.fd)
        except OSError:
            pass


def unlink_if_same(path: str, dev: int, ino: int) -> bool:
    """Unlink `path` only when it is the file (dev, ino); True when removed."""
    try:
        st = os.stat(path, follow_symlinks=False)
    except FileNotFoundError:
        return False
    if (st.st_dev, st.st_ino) != (dev, ino):
        return False
    return _unlink_quiet(path)


def _unlink_quiet(path: str) -> bool:
    try:
        os.unlink(path)
        return True
    except FileNotFoundError:
        return False
