"""A bound on batch sizes, checked before anything is allocated.

A batch of B samples of a model whose input is C x H x W passes through memory at least as the uint8 frames read
(1 byte a value), their float32 scaling and the normalised float32 copy (4 + 4 bytes): 9 C H W bytes a sample,
before any activation. A batch whose inputs alone would take more than half of the memory this machine has
available (MemAvailable) cannot run; it is refused in one line instead of dying in an allocation.
"""
from __future__ import annotations

import os

BYTES_PER_VALUE = 1 + 4 + 4   # uint8 frame, float32 scaled, float32 normalised
SHARE = 0.5                   # of the available memory the inputs may take (the rest: weights, activations)


class BatchTooLarge(ValueError):
    """A batch size whose inputs cannot fit in this machine's memory (the CLI: one line, exit status 2)."""


def available_memory() -> int:
    """Bytes of memory available to a new allocation (Linux: MemAvailable), else the free physical pages."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES")


def batch_input_bytes(batch: int, model_input: dict) -> int:
    """Bytes the inputs of a batch take at least: BYTES_PER_VALUE per input value."""
    return batch * model_input["channels"] * model_input["height"] * model_input["width"] * BYTES_PER_VALUE


def check_batch(batch: int, model_input: dict, option: str = "--batch-size", available: int | None = None) -> None:
    """BatchTooLarge when the batch's inputs alone would take more than SHARE of the available memory."""
    available = available_memory() if available is None else available
    need = batch_input_bytes(batch, model_input)
    if need > SHARE * available:
        most = max(1, int(SHARE * available // batch_input_bytes(1, model_input)))
        shape = f"{model_input['channels']} x {model_input['height']} x {model_input['width']}"
        raise BatchTooLarge(f"{option} {batch}: its inputs ({shape} a sample) alone need {need / 2**30:.1f} GiB, "
                            f"more than half of the {available / 2**30:.1f} GiB this machine has available; "
                            f"at most {most} fits")
