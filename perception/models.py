"""The model registry and the wrapper every model is used through.

A model family registers a `Family`: a builder that takes the input (channels, height, width, behavioural modes)
and the number of outputs, a test of which worlds it fits, how its input is scaled and how it is trained. The
families shipped: alexnet, vgg16, gist (the highway's regressors, one camera) and z2color (MultiNet, stereo moments
with a behavioural mode). `drivestudio train --model NAME` offers the families that fit the dataset's world.

A model is described by a `spec`, a plain JSON-able dict that a checkpoint stores beside the weights:
    name           the family
    world          the world's name; `labels` the targets it learns, `outputs` the output names (targets expanded
                   over the moment's horizon: "steer+1" .. "steer+10")
    options        family options (weights, frozen, batch_norm, regressor, seed, ...)
    input          {"channels", "height", "width", "instants", "cameras", "modes", "scaling", "mean", "std"}:
                   frames arrive as uint8 (B, channels, H, W) and are resized (area) to height x width;
                   scaling "standardise" maps them to [0, 1] then (x - mean) / std per channel (the training
                   frames' own statistics, or ImageNet's), "centre" to x / 255 - 0.5 (Z2Color)
    normalisation  {output: [scale, offset]}: the declaration's maps the targets were trained with
`Regressor(spec)` rebuilds the network; its forward takes (images, modes) and returns normalised outputs;
`denormalise` maps them back to the labels' units.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from core import worlds
from core.declaration import DeclarationError, WorldDeclaration
from perception.checkpoint import CheckpointError, load_checkpoint

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)
SCALINGS = ("standardise", "centre")


@dataclass(frozen=True)
class ModelInput:
    channels: int
    height: int
    width: int
    modes: int = 0       # behavioural modes fed beside the images (0: none)


@dataclass(frozen=True)
class Family:
    """A kind of model. build(input, outputs, options) -> nn.Module whose forward(x, modes) takes scaled float
    images (B, C, H, W) and mode indices (B,) (ignored by families without modes) and returns (B, outputs).

    fits(declaration) -> None when the family can learn that world, else why not (one line).
    size(declaration) -> (height, width) the family wants its input at (None: the camera's own).
    trainer: "sgd" (iterations of SGD/Adam on the Euclidean loss), "closed-form" (GIST + ridge) or "multinet"
    (epochs of Adadelta, MultiNet's losses and trials). defaults: the trainer's settings for this family.
    temporal: the family takes frames of earlier steps beside the current one (3 channels per instant), as many as
    the training setting `history` says. settings: the other settings of TrainConfig that only this family's training
    reads (perception/train.py's settings_read).
    onnx: None when the family can be exported as ONNX (`drivestudio export`), else why not (one line).
    drives_bf16: a predictor of the family computes under bfloat16 autocast where that is native
    (perception/precision.py), as its trainer does.
    """

    name: str
    title: str
    build: Callable[[ModelInput, int, dict], nn.Module]
    fits: Callable[[WorldDeclaration], str | None]
    scaling: str = "standardise"
    trainer: str = "sgd"
    size: Callable[[WorldDeclaration], tuple[int, int] | None] = lambda decl: None
    defaults: dict = field(default_factory=dict)
    describe: Callable[[dict], str] | None = None
    temporal: bool = False     # reads several instants of a one-instant world (the setting history)
    settings: tuple[str, ...] = ()   # settings of TrainConfig only this family reads (VGG-16's unfreeze, ...)
    onnx: str | None = None    # None: exportable to ONNX; else why not, e.g. an operator ONNX cannot express
    drives_bf16: bool = False


_FAMILIES: dict[str, Family] = {}
# the built-in families by name, each registered by importing its module; a checkpoint's family is imported alone
# (AlexNet, VGG-16 and MobileNet import torchvision, about a second of every command's start-up that loads Z2Color)
_BUILTIN = {"alexnet": "perception.alexnet", "vgg16": "perception.vgg", "gist": "perception.gist",
            "z2color": "perception.z2color", "mobilenet": "perception.mobilenet", "ensemble": "perception.ensemble"}
_loaded = False


def register(family: Family) -> Family:
    if family.scaling not in SCALINGS:
        raise ValueError(f"family {family.name}: scaling must be one of {SCALINGS}")
    _FAMILIES[family.name] = family
    return family


def _load_builtin() -> None:
    global _loaded
    if not _loaded:
        _loaded = True
        for module in _BUILTIN.values():
            importlib.import_module(module)


def families() -> dict[str, Family]:
    _load_builtin()
    return dict(_FAMILIES)


def family(name: str) -> Family:
    if name not in _FAMILIES and name in _BUILTIN:
        importlib.import_module(_BUILTIN[name])
    if name in _FAMILIES:
        return _FAMILIES[name]
    fams = families()
    if name not in fams:
        raise CheckpointError(f"unknown model '{name}' (families: {', '.join(sorted(fams))})")
    return fams[name]


def fitting(decl: WorldDeclaration) -> list[str]:
    """The families that can learn world `decl`."""
    return sorted(n for n, f in families().items() if f.fits(decl) is None)


def one_camera_now(decl: WorldDeclaration) -> str | None:
    """The highway regressors' test: one RGB camera, one instant, targets of the current step."""
    if len(decl.cameras) != 1 or decl.cameras[0].channels != 3:
        return f"it reads one RGB camera; the {decl.name} world has {len(decl.cameras)}"
    if decl.moment.instants != (0,) or decl.moment.horizon:
        return f"it reads the current frame only; the {decl.name} world's samples span several steps"
    return None


def make_spec(name: str, decl: WorldDeclaration, targets=None, mean=None, std=None, size=None,
              instants: tuple[int, ...] | None = None, **options) -> dict:
    """The spec of a new model of family `name` for world `decl` learning `targets` (default: the world's), reading
    the frames of `instants` (default: the world's data moment; earlier steps only for a temporal family)."""
    fam = family(name)
    why = fam.fits(decl)
    if why is not None:
        raise CheckpointError(f"a {name} model cannot learn the {decl.name} world: {why}")
    instants = tuple(decl.moment.instants if instants is None else instants)
    if instants != tuple(decl.moment.instants) and not fam.temporal:
        raise CheckpointError(f"a {name} model reads the {decl.name} world's instants {decl.moment.instants} only")
    targets = tuple(decl.targets if targets is None else targets)
    outputs = decl.outputs(targets)
    channels = len(instants) * sum(c.channels for c in decl.cameras)
    cam = decl.cameras[0]
    height, width = size or fam.size(decl) or (cam.height, cam.width)
    mean = [0.0] * channels if mean is None else [float(v) for v in mean]
    std = [1.0] * channels if std is None else [float(v) for v in std]
    if len(mean) != channels or len(std) != channels:
        raise ValueError(f"mean and std need {channels} values, one per input channel")
    inset = {"inset": cam.inset} if cam.inset else {}   # absent unless the frames hold one: older specs unchanged
    return {"name": name, "world": decl.name, "world_fingerprint": decl.fingerprint(), "labels": list(targets),
            "outputs": list(outputs), "options": dict(options),
            "input": {"channels": channels, "height": int(height), "width": int(width),
                      "instants": list(instants), "cameras": list(decl.camera_names),
                      "modes": list(decl.modes), "scaling": fam.scaling, "mean": mean, "std": std, **inset},
            "normalisation": decl.normalisation(outputs)}


def add_renderers(spec: dict, renderers) -> dict:
    """`spec` with `renderers` joined to the renderers of the frames its network learned from (a new network's data,
    a fine-tuning's further data, an ensemble's members); absent while none is known."""
    have = set(spec["input"].get("renderers", ())) | set(renderers)
    if have:
        spec["input"]["renderers"] = sorted(have)
    return spec


def frame_inset(spec: dict) -> str:
    """What the frames a model learned held besides the scene (core/declaration.py Camera.inset): "" or
    "mirror" or "mirror+sides". A world must render the same for the model to read it."""
    return str(spec["input"].get("inset", ""))


def declaration_of(spec: dict) -> WorldDeclaration:
    try:
        return worlds.get(spec["world"])
    except DeclarationError as e:
        raise CheckpointError(f"the model was trained for a world this installation does not know ({e})") from None


def family_title(spec: dict) -> str:
    """The family's own name for a spec, without the labels or inset beyond the paper's ("MobileNet (2 frames)")."""
    fam = family(spec["name"])
    return fam.describe(spec) if fam.describe else fam.title


def describe(spec: dict) -> str:
    """A short human name: "AlexNet", "VGG-16 (conv frozen, ImageNet)", "GIST + ridge", "Z2Color (MultiNet)"."""
    text = family_title(spec)
    extra = [n for n in spec["labels"] if n in ("fast", "lanes_left")]
    inset = frame_inset(spec)
    return text + (f" [+{', '.join(extra)}]" if extra else "") + (f" with {inset}" if inset else "")


def _block_mean(x: torch.Tensor, fh: int, fw: int) -> torch.Tensor:
    """Area resampling by a whole-number factor: the mean of each fh x fw block, in float32. As a sum of strided
    slices it is 4.5x faster on the CPU than interpolate(mode="area") or avg_pool2d (at batch 1 those took a third
    of Z2Color's time); on frames of whole numbers the sums are exact, so for 2 x 2 blocks the result equals
    theirs bit for bit.
    uint8 frames are summed in 16-bit integers, each slice converted as it is added (exact too): for a batch of two
    frames a sample (6 channels) 3x faster on one thread than converting the frames to floats first, which took
    27 ms of a MobileNet's training step of about 360; for one frame (3 channels) about as fast as before."""
    whole = x.dtype == torch.uint8 and fh * fw * 255 <= torch.iinfo(torch.int16).max
    total = x[..., 0::fh, 0::fw].to(torch.int16 if whole else torch.float32)
    for k in range(1, fh * fw):
        i, j = divmod(k, fw)
        total = total + x[..., i::fh, j::fw]
    return total.float() / (fh * fw)


class Regressor(nn.Module):
    """Input handling + network. forward: uint8 images (B, C, H, W) and modes (B,) -> normalised outputs (B, N)."""

    def __init__(self, spec: dict) -> None:
        super().__init__()
        self.spec = spec
        self.name = spec["name"]
        self.labels = tuple(spec["labels"])
        self.outputs = tuple(spec["outputs"])
        fam = family(self.name)
        inp = spec["input"]
        self.size = (int(inp["height"]), int(inp["width"]))
        self.scaling = inp.get("scaling", fam.scaling)
        self.modes = tuple(inp.get("modes", ()))
        self.net = fam.build(ModelInput(int(inp["channels"]), *self.size, len(self.modes)), len(self.outputs),
                             dict(spec.get("options", {})))
        c = int(inp["channels"])
        self.register_buffer("mean", torch.tensor(inp["mean"], dtype=torch.float32).view(1, c, 1, 1))
        self.register_buffer("std", torch.tensor(inp["std"], dtype=torch.float32).view(1, c, 1, 1))
        self._scale = np.array([spec["normalisation"][n][0] for n in self.outputs], dtype=np.float32)
        self._offset = np.array([spec["normalisation"][n][1] for n in self.outputs], dtype=np.float32)
        self._tables: dict = {}     # scale_pixels' tables by dtype, scale_input's by block (_sum_table)

    def scale_input(self, images: torch.Tensor) -> torch.Tensor:
        """uint8 frames -> the network's input: resized (area) to its size and scaled."""
        h, w = images.shape[-2:]
        fh, fw = h // self.size[0], w // self.size[1]
        if (h, w) == (fh * self.size[0], fw * self.size[1]) and self._compiled_path(images, fh * fw):
            from perception.input_kernels import block_lookup  # numba: only where frames are scaled
            table = self._sum_table(fh, fw)
            if table is not None:
                pixels = images.permute(0, 2, 3, 1).numpy()
                return torch.from_numpy(block_lookup(pixels, (fh, fw), table)).permute(0, 3, 1, 2)
        if (h, w) == self.size:
            x = images.float()
        elif (h, w) == (fh * self.size[0], fw * self.size[1]):
            x = _block_mean(images, fh, fw)
        else:
            x = F.interpolate(images.float(), size=self.size, mode="area")
        return self._scale_values(x, images.dtype == torch.uint8)

    def _compiled_path(self, images: torch.Tensor, block: int = 1) -> bool:
        """Whether perception/input_kernels.py's block_lookup computes scale_input: uint8 channels-last frames on
        the CPU (what training and driving pass) in blocks of at most 16 pixels, outside tracing and compilation
        (ONNX export, torch.compile)."""
        return (images.device.type == "cpu" and images.dtype == torch.uint8 and images.dim() == 4 and block <= 16
                and images.is_contiguous(memory_format=torch.channels_last)
                and self.get_buffer("mean").device.type == "cpu"
                and not torch.jit.is_tracing() and not torch.compiler.is_compiling())

    def _sum_table(self, fh: int, fw: int) -> np.ndarray | None:
        """(fh x fw x 255 + 1, C) float32: what scale_input makes of an fh x fw block of channel c whose pixels sum
        to s, at [s, c], computed by scale_input's own tensor arithmetic (so a lookup is that arithmetic bit for
        bit), each value at many positions so that a vectorised and a scalar path of it would show any difference
        (then None: no table)."""
        mean, std = self.get_buffer("mean"), self.get_buffer("std")
        key = ("sums", fh, fw, tuple(mean.reshape(-1).tolist()), tuple(std.reshape(-1).tolist()))  # loaded buffers
        if key not in self._tables:
            c, sums = int(mean.numel()), fh * fw * 255 + 1
            total = torch.arange(sums, dtype=torch.float32).expand(1, c, 67, sums)     # 67 rows: odd strides
            means = total / (fh * fw) if fh * fw > 1 else total
            scaled = self._scale_values(means, True)
            same = bool((scaled == scaled[:, :, :1]).all())
            self._tables[key] = scaled[0, :, 0].t().contiguous() if same else None
        table = self._tables[key]
        return None if table is None else table.numpy()

    def _scale_values(self, x: torch.Tensor, from_uint8: bool) -> torch.Tensor:
        if self.scaling == "centre":
            return x / 255.0 - 0.5
        if from_uint8:
            x = x / 255.0
        mean, std = self.get_buffer("mean"), self.get_buffer("std")
        return (x - mean) / std

    def scale_pixels(self, pixels: np.ndarray, dtype: torch.dtype = torch.float32) -> torch.Tensor | None:
        """uint8 pixels (B, h, w, C), C-contiguous, already at the network's size -> scale_input of them cast to
        `dtype`, bit for bit, (B, C, h, w) channels-last, through a table of the 256 values: one pass instead of
        scale_input's four (conversion, division, subtraction, cast), which with the batch's assembly took a
        quarter of Z2Color's training step beside it on one core. None where the table does not apply (a scaling
        that differs per channel, pixels to be resized)."""
        table = self.pixel_table(dtype)
        if table is None or pixels.dtype != np.uint8 or tuple(pixels.shape[1:3]) != self.size:
            return None
        scaled = table[np.ascontiguousarray(pixels)]        # the result takes the index array's layout
        return torch.from_numpy(scaled).view(dtype).permute(0, 3, 1, 2)

    def pixel_table(self, dtype: torch.dtype = torch.float32) -> np.ndarray | None:
        """What scale_input makes of each of the 256 pixel values, cast to `dtype`, as a numpy array (bfloat16's
        bits as int16: numpy has no bfloat16); None where one table does not apply (a scaling that differs per
        channel)."""
        if self.scaling != "centre":
            return None
        table = self._value_table(dtype)
        if table is None:
            return None
        return (table.view(torch.int16) if dtype == torch.bfloat16 else table).numpy()

    def _value_table(self, dtype: torch.dtype) -> torch.Tensor | None:
        """The 256 scaled values in `dtype`, computed by the arithmetic scale_input uses, with every value at many
        positions of a tensor so that a vectorised and a scalar path of that arithmetic would show any difference
        (then None: no table)."""
        tables = self._tables
        if dtype not in tables:
            values = torch.arange(256, dtype=torch.uint8).repeat(67, 1)               # 67 rows: odd strides
            scaled = self._scale_values(values.float(), True).to(dtype)
            tables[dtype] = scaled[0].clone() if bool((scaled == scaled[0]).all()) else None
        return tables[dtype]

    def forward(self, images: torch.Tensor, modes: torch.Tensor | None = None) -> torch.Tensor:
        if modes is None:
            modes = torch.full((images.shape[0],), -1, dtype=torch.int64, device=images.device)
        return self.net(self.scale_input(images), modes)

    def denormalise(self, outputs) -> np.ndarray:
        """Network outputs (..., N) -> values in the labels' units."""
        if isinstance(outputs, torch.Tensor):
            outputs = outputs.detach().float().cpu().numpy()
        return ((np.asarray(outputs, dtype=np.float32) - self._offset) / self._scale).astype(np.float64)


def build(name: str, decl: WorldDeclaration, targets=None, **kwargs) -> Regressor:
    return Regressor(make_spec(name, decl, targets, **kwargs))


def check_spec(spec: dict, where: str) -> WorldDeclaration:
    """The world a spec was trained for, after checking that its outputs and normalisation are that world's
    (a model trained with other maps would be read back wrongly)."""
    decl = declaration_of(spec)
    for n in spec["outputs"]:
        try:
            lab = decl.label(n)
        except DeclarationError:
            raise CheckpointError(f"{where}: the model predicts '{n}', which the {decl.name} world does not "
                                  "declare") from None
        if not np.allclose(spec["normalisation"].get(n, [np.nan, np.nan]), [lab.scale, lab.offset], rtol=0,
                           atol=1e-9):
            raise CheckpointError(f"{where} was trained with another normalisation of '{n}' than the "
                                  f"{decl.name} world declares; retrain it")
    return decl


def load_trunk(model: Regressor, path: str) -> int:
    """Copy the convolutional trunk of a torchvision ImageNet state dict (vgg16, vgg16_bn or alexnet; e.g.
    `vgg16-397923af.pth`) into `model`. Nothing is downloaded. Returns the number of tensors copied."""
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise CheckpointError(f"no weights file at {path}") from None
    except Exception as e:  # pickled code, truncated or not a torch file at all
        raise CheckpointError(f"{path} is not a torchvision state dict ({type(e).__name__})") from None
    if isinstance(state, dict) and isinstance(state.get("state_dict"), dict):
        state = state["state_dict"]
    if not isinstance(state, dict):
        raise CheckpointError(f"{path} is not a torchvision state dict")
    features = model.net.get_submodule("features")
    want = features.state_dict()
    got = {k[len("features."):]: v for k, v in state.items() if isinstance(k, str) and k.startswith("features.")}
    kind = {"alexnet": "AlexNet", "vgg16": "VGG-16-BN" if model.spec["options"].get("batch_norm") else "VGG-16"}
    if set(got) != set(want) or any(tuple(got[k].shape) != tuple(want[k].shape) for k in want):
        raise CheckpointError(f"{path} is not a torchvision {kind.get(model.name, model.name)} ImageNet state "
                              "dict (its convolutional layers do not match)")
    features.load_state_dict(got)
    return len(got)


def load_model(path, model: str | None = None, labels=None, device="cpu", world: str | None = None):
    """The model of a checkpoint, in eval mode on `device`: (Regressor, checkpoint dict)."""
    ckpt = load_checkpoint(path, model=model, labels=labels, world=world)
    check_spec(ckpt["spec"], str(path))
    net = Regressor(ckpt["spec"])
    try:
        net.load_state_dict(ckpt["state_dict"])
    except RuntimeError as e:
        raise CheckpointError(f"{path}: the weights do not fit its {ckpt['spec']['name']} model "
                              f"({str(e).splitlines()[0]})") from None
    return net.to(device).eval(), ckpt
