"""The GIST baseline of Liu and Wang (Deeper Direct Perception, Table 3): a scene descriptor and a regularised
regressor on it.

GIST (Oliva & Torralba 2001; the LMgist reference code): the frame is made grey, resized, log-compressed,
whitened and contrast-normalised (the pre-filter); Gabor filters of 4 scales x 8 orientations are applied in
the frequency domain and each filter's energy |response| is averaged over a 4x4 grid: 512 numbers. The
regressor is ridge regression in closed form, on the standardised descriptor (`ridge`) or on random Fourier
features of an RBF kernel (`rbf`, an approximate kernel ridge). No gradient descent: fitting is one solve.
"""
from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from perception.models import Family, ModelInput, one_camera_now, register

ORIENTATIONS = (8, 8, 8, 8)  # orientations per scale, finest scale first
GRID = 4                     # energies are averaged over GRID x GRID cells
SIZE = (120, 160)            # (h, w) of the grey image the descriptor sees: 280x210 frames halved, 4:3 kept
BOUNDARY = 20                # [px] symmetric padding against FFT wrap-around
PREFILTER_FC = 4.0           # cut-off of the whitening filter, in cycles per image (LMgist's fc_prefilt)
RFF_FEATURES = 4096          # random Fourier features of the `rbf` regressor
REGRESSORS = ("ridge", "rbf")


def _frequencies(h: int, w: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Radial frequency [cycles/pixel] and orientation [rad] of each bin of an h x w FFT (unshifted layout)."""
    fy = torch.fft.fftfreq(h, dtype=torch.float64)[:, None].expand(h, w)
    fx = torch.fft.fftfreq(w, dtype=torch.float64)[None, :].expand(h, w)
    return torch.sqrt(fx ** 2 + fy ** 2), torch.atan2(fy, fx)


def gabor_bank(h: int, w: int, orientations=ORIENTATIONS) -> torch.Tensor:
    """LMgist's createGabor: one transfer function per (scale, orientation), shape (filters, h, w)."""
    fr, theta = _frequencies(h, w)
    filters = []
    for scale, n in enumerate(orientations):
        peak = 0.3 / 1.85 ** scale          # centre frequency [cycles/pixel]
        spread = 16 * n ** 2 / 32 ** 2      # angular selectivity
        for k in range(n):
            t = theta + math.pi / n * k
            t = t + 2 * math.pi * (t < -math.pi) - 2 * math.pi * (t > math.pi)
            filters.append(torch.exp(-10 * 0.35 * (fr / peak - 1) ** 2 - 2 * spread * math.pi * t ** 2))
    return torch.stack(filters).float()


class GistDescriptor(nn.Module):
    """Frames (B, 3, H, W) with values in [0, 1] -> GIST descriptors (B, filters * GRID * GRID)."""

    gabor: torch.Tensor      # buffers (register_buffer), named for the type checker
    lowpass: torch.Tensor

    def __init__(self, size=SIZE, orientations=ORIENTATIONS, grid: int = GRID, boundary: int = BOUNDARY):
        super().__init__()
        self.size, self.grid, self.boundary = tuple(size), grid, boundary
        h, w = self.size
        ph, pw = h + 2 * boundary, w + 2 * boundary
        # Deterministic functions of the options: rebuilt, not stored in checkpoints.
        # complex, as the spectra it multiplies: no conversion a frame
        self.register_buffer("gabor", gabor_bank(ph, pw, orientations).to(torch.complex64), persistent=False)
        n = max(ph, pw)
        fr, _ = _frequencies(ph, pw)
        sigma = PREFILTER_FC / math.sqrt(math.log(2))
        self.register_buffer("lowpass", torch.exp(-(fr * n) ** 2 / sigma ** 2).float(), persistent=False)
        self.dim = self.gabor.shape[0] * grid * grid

    def prefilter(self, grey: torch.Tensor) -> torch.Tensor:
        """Whitening and local contrast normalisation of log-intensities (B, h+2b, w+2b)."""
        x = torch.log1p(grey)
        x = x - torch.fft.ifft2(torch.fft.fft2(x) * self.lowpass).real
        local = torch.sqrt(torch.fft.ifft2(torch.fft.fft2(x * x) * self.lowpass).abs())
        return x / (0.2 + local)

    def grey(self, images: torch.Tensor) -> torch.Tensor:
        """Frames (B, 3, H, W) in [0, 1] -> grey levels at the descriptor's size, padded by reflection (B, h+2b,
        w+2b)."""
        images = images.float()
        weights = images.new_tensor([0.299, 0.587, 0.114]).view(1, 3, 1, 1)
        grey = (images * weights).sum(1, keepdim=True) * 255.0
        grey = F.interpolate(grey, size=self.size, mode="bilinear", antialias=True, align_corners=False)
        b = self.boundary
        return F.pad(grey, (b, b, b, b), mode="reflect")[:, 0]

    def forward(self, images: torch.Tensor, chunk: int = 2) -> torch.Tensor:
        grey, b = self.grey(images), self.boundary
        out = []
        # two frames' 32 complex responses (16 MB) stay in the cache between the transform and the energies: 2.5x
        # faster a frame than 16 at a time
        for part in grey.split(chunk):
            spectrum = torch.fft.fft2(self.prefilter(part))
            response = torch.view_as_real(torch.fft.ifft2(spectrum[:, None] * self.gabor[None])[..., b:-b, b:-b])
            energy = torch.hypot(response[..., 0], response[..., 1])   # |response| of the kept pixels only
            out.append(F.adaptive_avg_pool2d(energy, self.grid).flatten(1))
        return torch.cat(out)


class GistRegressor(nn.Module):
    """GIST descriptor + ridge (or random-Fourier-feature kernel ridge) head; fitted by `fit`, not by SGD."""

    feature_mean: torch.Tensor   # buffers (register_buffer), named for the type checker
    feature_std: torch.Tensor
    rff_weight: torch.Tensor     # rbf only
    rff_phase: torch.Tensor
    rff_width: torch.Tensor
    weight: torch.Tensor
    bias: torch.Tensor

    def __init__(self, num_outputs: int = 13, regressor: str = "ridge", rff_features: int = RFF_FEATURES,
                 seed: int = 0) -> None:
        super().__init__()
        if regressor not in REGRESSORS:
            raise ValueError(f"unknown GIST regressor '{regressor}' (choose from {', '.join(REGRESSORS)})")
        self.descriptor = GistDescriptor()
        self.regressor = regressor
        d = self.descriptor.dim
        self.register_buffer("feature_mean", torch.zeros(d))
        self.register_buffer("feature_std", torch.ones(d))
        width = d
        if regressor == "rbf":
            g = torch.Generator().manual_seed(seed)
            self.register_buffer("rff_weight", torch.randn(d, rff_features, generator=g))
            self.register_buffer("rff_phase", torch.rand(rff_features, generator=g) * 2 * math.pi)
            self.register_buffer("rff_width", torch.tensor(math.sqrt(2 * d)))  # kernel width, set by fit
            width = rff_features
        self.register_buffer("weight", torch.zeros(width, num_outputs))
        self.register_buffer("bias", torch.full((num_outputs,), 0.5))

    def lift(self, descriptors: torch.Tensor) -> torch.Tensor:
        """Descriptors -> the regressor's input: standardised, then (rbf) random Fourier features."""
        z = (descriptors - self.feature_mean) / self.feature_std
        if self.regressor == "rbf":
            scale = math.sqrt(2.0 / self.rff_weight.shape[1])
            z = torch.cos(z @ self.rff_weight / self.rff_width + self.rff_phase) * scale
        return z

    def forward(self, x: torch.Tensor, modes: torch.Tensor | None = None) -> torch.Tensor:
        return self.lift(self.descriptor(x)) @ self.weight + self.bias

    @torch.no_grad()
    def fit(self, descriptors: torch.Tensor, targets: torch.Tensor, val_descriptors: torch.Tensor,
            val_targets: torch.Tensor, alphas=None) -> list[dict]:
        """Closed-form ridge on training descriptors; the ridge strength is the one with the lowest validation
        Euclidean loss. Returns the sweep, one {alpha, train_loss, val_loss} per strength tried."""
        descriptors, targets = descriptors.double(), targets.double()
        self.feature_mean.copy_(descriptors.mean(0))
        self.feature_std.copy_(descriptors.std(0).clamp_min(1e-6))
        if self.regressor == "rbf":  # kernel width: the median distance between standardised descriptors
            z = (descriptors - self.feature_mean.double()) / self.feature_std.double()
            sample = z[torch.randperm(len(z), generator=torch.Generator().manual_seed(0))[:500]]
            self.rff_width.copy_(torch.cdist(sample, sample).median().clamp_min(1e-3))
        z = self.lift(descriptors.float()).double()
        zv = self.lift(val_descriptors.float()).double()
        z_mean, y_mean = z.mean(0), targets.mean(0)
        zc, yc = z - z_mean, targets - y_mean
        evals, evecs = torch.linalg.eigh(zc.T @ zc)
        proj = evecs.T @ (zc.T @ yc)
        scale = float(evals.clamp_min(0).mean())
        alphas = alphas if alphas is not None else [10.0 ** k for k in range(-6, 3)]
        sweep: list[dict] = []
        best: tuple[dict, torch.Tensor, torch.Tensor] | None = None
        for alpha in alphas:
            w = evecs @ (proj / (evals.clamp_min(0) + alpha * scale)[:, None])
            b = y_mean - z_mean @ w

            def loss(zz, yy, w=w, b=b) -> float:
                return float(((zz @ w + b - yy) ** 2).sum(1).mean() / 2)
            row = {"alpha": alpha, "train_loss": loss(z, targets), "val_loss": loss(zv, val_targets.double())}
            sweep.append(row)
            if best is None or row["val_loss"] < best[0]["val_loss"]:
                best = (row, w, b)
        if best is None:
            raise ValueError("GIST fit: no ridge strength to try")
        self.weight.copy_(best[1].float())
        self.bias.copy_(best[2].float())
        return sweep


def gist(num_outputs: int = 13, regressor: str = "ridge", seed: int = 0) -> GistRegressor:
    return GistRegressor(num_outputs, regressor=regressor, seed=seed)


def _build(inp: ModelInput, outputs: int, options: dict) -> GistRegressor:
    return GistRegressor(outputs, regressor=options.get("regressor", "ridge"), seed=int(options.get("seed", 0)))


register(Family("gist", "GIST", _build, one_camera_now, trainer="closed-form",
                defaults={"batch_size": 32},
                onnx="its anti-aliased resize of the frame (and its 2-D Fourier transforms) have no ONNX operator",
                describe=lambda spec: f"GIST + {spec['options'].get('regressor', 'ridge')}"))
