"""The regressors' input path compiled with numba: a sample's frames side by side in its channels, a batch of frames
averaged by blocks and scaled in one pass, and MultiNet's images scaled through a table as they are gathered. Each
computes what the tensor code it replaces computes, bit for bit (perception/models.py's Regressor.scale_input,
perception/datasets.py's _stack, perception/moments.py's images; tests/perception/test_input_kernels.py).

Why: in a MobileNet's training step on one core (batch 32, two frames a sample, 280x210) numpy's concatenation of a
sample's frames along their 3 channels took 12 ms and the block mean and scaling of the batch 12 ms of about 108: the
tensor code passes over the batch several times (a slice, a conversion, a sum, a division, a subtraction, a
division). The scaling here is a lookup in a table scale_input's own arithmetic computed, of every block sum.
Assembling a batch of 120 MultiNet moments (four 94x168 images each) by gathering the images, interleaving them and
looking every byte up with numpy took 44 ms in the trainer; gathered and looked up in one pass, 15.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _interleave(a, b, out):
    """Flat frames of 3 channels a pixel -> out, 6 a pixel (a compiler vectorises this form)."""
    for p in range(a.shape[0] // 3):
        q, r = 3 * p, 6 * p
        out[r] = a[q]
        out[r + 1] = a[q + 1]
        out[r + 2] = a[q + 2]
        out[r + 3] = b[q]
        out[r + 4] = b[q + 1]
        out[r + 5] = b[q + 2]


def interleave(images: list) -> np.ndarray:
    """(h, w, c) uint8 frames -> one (h, w, c x len) array, the frames' channels one after another (what
    np.concatenate(images, axis=2) makes, which other numbers of frames and channels get)."""
    a = images[0]
    if len(images) != 2 or a.shape[2] != 3 or not all(image.flags.c_contiguous for image in images):
        return np.concatenate(images, axis=2)
    out = np.empty((*a.shape[:2], 6), dtype=np.uint8)
    _interleave(a.reshape(-1), images[1].reshape(-1), out.reshape(-1))
    return out


@njit(cache=True, nogil=True)
def _place_looked_up(image, table, out, first):
    h, w, c = image.shape
    for i in range(h):
        for j in range(w):
            for k in range(c):
                out[i, j, first + k] = table[image[i, j, k]]


def place_looked_up(image: np.ndarray, table: np.ndarray, out: np.ndarray, first: int) -> None:
    """out[:, :, first:first + c] = table[image] for an (h, w, c) uint8 image and an (h, w, C) out of table's type:
    a sample's image scaled through a table of the 256 values, written straight into its channels."""
    _place_looked_up(image, table, out, first)


@njit(cache=True, nogil=True)
def _block_lookup(src, fh, fw, table, out):
    """src (B, H, W, C) uint8 -> out (B, H / fh, W / fw, C): table[s, c] for the sum s of each fh x fw block of
    channel c. Each output row's source rows are summed first (contiguous: vectorised), then the blocks across."""
    n_b, height, width, n_c = src.shape
    h, w = out.shape[1], out.shape[2]
    rows = src.reshape(n_b, height, width * n_c)
    outs = out.reshape(n_b, h, w * n_c)
    values = table.reshape(-1)
    column = np.empty(width * n_c, np.int32)
    for b in range(n_b):
        for i in range(h):
            first = rows[b, i * fh]
            for q in range(width * n_c):
                column[q] = first[q]
            for di in range(1, fh):
                more = rows[b, i * fh + di]
                for q in range(width * n_c):
                    column[q] += more[q]
            line = outs[b, i]
            for j in range(w):
                base = j * fw * n_c
                for c in range(n_c):
                    total = column[base + c]
                    for dj in range(1, fw):
                        total += column[base + dj * n_c + c]
                    line[j * n_c + c] = values[total * n_c + c]


def block_lookup(pixels: np.ndarray, factor: tuple[int, int], table: np.ndarray) -> np.ndarray:
    """uint8 pixels (B, H, W, C), C-contiguous -> (B, H / fh, W / fw, C) of table's type: for each fh x fw block and
    channel c, table[the block's sum, c] (table: (fh x fw x 255 + 1, C), what the block's mean scales to)."""
    fh, fw = factor
    n_b, height, width, n_c = pixels.shape
    out = np.empty((n_b, height // fh, width // fw, n_c), dtype=table.dtype)
    _block_lookup(pixels, fh, fw, np.ascontiguousarray(table), out)
    return out
