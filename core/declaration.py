"""What a world declares about itself, once: its cameras, its labels, its per-step truth record, its action, its
behavioural modes and how a training sample (a data moment) is assembled from recorded steps.

The shared-memory layout (shm_bridge/layout.py), the dataset schema (perception/shards.py), the readers, the
model registry, training, evaluation and the CLI options are all derived from a `WorldDeclaration`; none of them
names a world's fields. The declarations themselves live in core/worlds/ (one module per world), at the
bottom of the dependency graph, so sim, perception and controller can all read them without importing each other.
A declaration is plain data: it round-trips through JSON (`to_json` / `from_json`), which is how a dataset
manifest, a checkpoint and the bridge header carry it.

This module imports only numpy.
"""
from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace

import numpy as np

NAME = re.compile(r"[A-Za-z][A-Za-z0-9_+]{0,30}")     # field, label, camera and mode names (C identifiers + '+')
SCALAR_KINDS = ("f32", "f64", "i8", "i32", "i64", "bool")   # how a dataset stores a scalar of the truth record
INSETS = ("", "mirror", "mirror+sides")   # what a world may composite into a camera's image (Camera.inset)
COLUMN_KIND = re.compile(r"(str|f32|f64)(\[\d+\])?(\*)?")   # str, f32[5] (fixed list), f32[5]* (list of them)


class DeclarationError(ValueError):
    """A declaration that contradicts itself, or data that does not fit a declaration."""


def _name(value: str, what: str) -> str:
    if not isinstance(value, str) or not NAME.fullmatch(value):
        raise DeclarationError(f"{what} name {value!r} must be 1-31 characters of A-Z a-z 0-9 _ + "
                               "starting with a letter")
    return value


@dataclass(frozen=True)
class Camera:
    """One camera of the world: its name and the size of the RGB image it renders [px]. `inset` names what the
    world composites into that image besides the scene ("" nothing; "mirror": a rear-view mirror; "mirror+sides": it
    and the views out of both side windows, docs/rendering.md): a model learns the frames it was shown, so it is part
    of what a frame means."""

    name: str
    height: int
    width: int
    channels: int = 3
    inset: str = ""

    def __post_init__(self):
        if self.inset not in INSETS:
            raise DeclarationError(f"camera {self.name!r}: unknown inset {self.inset!r} (known: "
                                   f"{', '.join(repr(i) for i in INSETS)})")

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.height, self.width, self.channels)

    @property
    def size(self) -> int:
        """Bytes of one image (uint8)."""
        return self.height * self.width * self.channels


@dataclass(frozen=True)
class Quantity:
    """One scalar of the per-step truth record: float64 on the bridge, `kind` in a dataset."""

    name: str
    unit: str = ""
    meaning: str = ""
    kind: str = "f32"


@dataclass(frozen=True)
class Label:
    """A quantity perception learns. Training targets are normalised as value * scale + offset (then clipped to
    `clip` when given); `inactive` is the value the label takes when it does not apply (None: always applies)."""

    name: str
    unit: str = ""
    meaning: str = ""
    scale: float = 1.0
    offset: float = 0.0
    clip: tuple[float, float] | None = None
    inactive: float | None = None


@dataclass(frozen=True)
class Control:
    """One value of the world's action: its range and its neutral value (what a world applies when no driver has
    answered yet)."""

    name: str
    unit: str = ""
    meaning: str = ""
    low: float = -1.0
    high: float = 1.0
    neutral: float = 0.0


@dataclass(frozen=True)
class Column:
    """A recorded dataset column that is not a scalar of the truth record: `str`, `f32[5]` (a fixed-length list)
    or `f32[5]*` (a list of fixed-length lists, e.g. the other cars' poses)."""

    name: str
    kind: str
    meaning: str = ""


@dataclass(frozen=True)
class Moment:
    """How one training sample is assembled from the consecutive recorded steps of an episode.

    instants: step offsets of the images it shows, oldest first ((0,): the current step only; MultiNet's data
    moment: (-1, 0), the stereo pair now and one step earlier). horizon: 0 means the labels of the current step are
    the targets; n means each target label is taken at the n following steps (t+1 .. t+n), output names
    "label+k". Every step of an episode that has all the steps it needs starts one sample; images are stored once.
    """

    instants: tuple[int, ...] = (0,)
    horizon: int = 0

    @property
    def earliest(self) -> int:
        return min(self.instants)


def expand(names, horizon: int) -> tuple[str, ...]:
    """Output names of targets over a horizon: ("steer", "motor"), 2 -> steer+1, steer+2, motor+1, motor+2."""
    names = tuple(names)
    if horizon <= 0:
        return names
    return tuple(f"{n}+{k}" for n in names for k in range(1, horizon + 1))


def base_name(output: str) -> str:
    """The label an output name stands for: "steer+10" -> "steer"."""
    return output.split("+", 1)[0]


@dataclass(frozen=True)
class WorldDeclaration:
    """Everything the generic machinery knows of a world.

    truth: the scalar per-step record, in order: it travels over the bridge (float64) and is stored in datasets
    (typed by kind); every label is also a truth field of the same name. columns: what datasets record besides
    (strings, lists). action: the driver's command, in order. modes: behavioural modes (shared flag `behaviour` on
    the bridge; `mode_field` of the truth record holds the index). targets: the labels a model learns by default.
    label_sets: named lists of labels a model may learn instead (`train --targets NAME`). observable: the truth
    fields a driving agent may read (the Gymnasium environments' affordance observation): what the car could sense
    of its surroundings and itself, not the map position nor the outcomes its reward scores. decisive: (label,
    bound) pairs; a step on which any of these labels is below its bound is one on which the world's driver makes
    a rare, costly decision (the highway: a car near ahead in a neighbouring lane), which `train --set emphasis=W`
    counts W times an epoch (by the labels among the model's targets: a network does not learn a decision from
    labels it does not estimate).
    """

    name: str
    title: str
    dt: float                                     # [s] one step
    cameras: tuple[Camera, ...]
    labels: tuple[Label, ...]
    truth: tuple[Quantity, ...]
    action: tuple[Control, ...]
    columns: tuple[Column, ...] = ()
    modes: tuple[str, ...] = ()
    mode_field: str | None = None
    moment: Moment = Moment()
    targets: tuple[str, ...] = ()
    label_sets: tuple[tuple[str, tuple[str, ...]], ...] = ()   # named target lists: (("paper", (...)), ...)
    observable: tuple[str, ...] = ()              # truth fields an agent may observe (the affordance observation)
    decisive: tuple[tuple[str, float], ...] = ()  # (label, bound): steps with a label below it decide (see above)
    version: int = 1                              # bump when the meaning of a field changes
    _index: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        _name(self.name, "world")
        if not (isinstance(self.dt, (int, float)) and math.isfinite(self.dt) and self.dt > 0):
            raise DeclarationError(f"world {self.name!r}: dt must be a positive number of seconds")
        if not self.cameras:
            raise DeclarationError(f"world {self.name!r} declares no camera")
        for group, items in (("camera", self.cameras), ("label", self.labels), ("truth field", self.truth),
                             ("action value", self.action), ("column", self.columns)):
            seen = set()
            for item in items:
                _name(item.name, group)
                if item.name in seen:
                    raise DeclarationError(f"world {self.name!r}: {group} {item.name!r} is declared twice")
                seen.add(item.name)
        for m in self.modes:
            _name(m, "mode")
        for c in self.cameras:
            if not (0 < c.height <= 4096 and 0 < c.width <= 4096 and c.channels in (1, 3)):
                raise DeclarationError(f"world {self.name!r}: camera {c.name!r} has an unusable size")
        index = {q.name: i for i, q in enumerate(self.truth)}
        for q in self.truth:
            if q.kind not in SCALAR_KINDS:
                raise DeclarationError(f"truth field {q.name!r}: kind must be one of {', '.join(SCALAR_KINDS)}")
        for col in self.columns:
            if not COLUMN_KIND.fullmatch(col.kind):
                raise DeclarationError(f"column {col.name!r}: kind {col.kind!r} is not str, f32[N] or f32[N]*")
            if col.name in index:
                raise DeclarationError(f"column {col.name!r} is also a truth field")
        missing = [lab.name for lab in self.labels if lab.name not in index]
        if missing:
            raise DeclarationError(f"world {self.name!r}: labels {missing} are not fields of the truth record")
        unknown = [t for t in self.targets if t not in {lab.name for lab in self.labels}]
        if unknown:
            raise DeclarationError(f"world {self.name!r}: default targets {unknown} are not labels")
        for set_name, names in self.label_sets:
            _name(set_name, "label set")
            unknown = [n for n in names if n not in {lab.name for lab in self.labels}]
            if not names or unknown:
                raise DeclarationError(f"world {self.name!r}: label set {set_name!r} names no label or unknown "
                                       f"labels {unknown}")
        unknown = [n for n in self.observable if n not in index]
        if unknown or len(set(self.observable)) != len(self.observable):
            raise DeclarationError(f"world {self.name!r}: observable fields {unknown or list(self.observable)} are "
                                   "not distinct fields of the truth record")
        unknown = [n for n, bound in self.decisive if n not in {lab.name for lab in self.labels}
                   or not (isinstance(bound, (int, float)) and math.isfinite(bound))]
        if unknown:
            raise DeclarationError(f"world {self.name!r}: decisive steps name unknown labels or bounds {unknown}")
        if self.modes and (self.mode_field is None or self.mode_field not in index):
            raise DeclarationError(f"world {self.name!r}: behavioural modes need a mode_field of the truth record")
        if not self.moment.instants or self.moment.horizon < 0 or max(self.moment.instants) > 0:
            raise DeclarationError(f"world {self.name!r}: a moment shows the current step or earlier ones")
        for a in self.action:
            if not (a.low <= a.neutral <= a.high):
                raise DeclarationError(f"action value {a.name!r}: neutral must lie in [low, high]")
        self._index.update(index)

    # --- names ---------------------------------------------------------------------------------------------------
    @property
    def truth_names(self) -> tuple[str, ...]:
        return tuple(q.name for q in self.truth)

    @property
    def label_names(self) -> tuple[str, ...]:
        return tuple(lab.name for lab in self.labels)

    @property
    def action_names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.action)

    @property
    def camera_names(self) -> tuple[str, ...]:
        return tuple(c.name for c in self.cameras)

    @property
    def estimate_names(self) -> tuple[str, ...]:
        """The driver's estimate on the bridge: every label, expanded over the moment's horizon."""
        return expand(self.label_names, self.moment.horizon)

    def outputs(self, targets=None) -> tuple[str, ...]:
        """A model's output names for `targets` (default: the declaration's targets)."""
        return expand(self.targets if targets is None else targets, self.moment.horizon)

    def label_set(self, name: str) -> tuple[str, ...]:
        """The labels of the named label set, or DeclarationError naming the sets there are."""
        for set_name, names in self.label_sets:
            if set_name == name:
                return tuple(names)
        known = ", ".join(n for n, _ in self.label_sets) or "none"
        raise DeclarationError(f"the {self.name} world has no label set {name!r} (label sets: {known})")

    def index(self, name: str) -> int:
        """Position of a truth field in the record."""
        try:
            return self._index[name]
        except KeyError:
            raise DeclarationError(f"world {self.name!r} has no truth field {name!r}") from None

    def label(self, name: str) -> Label:
        base = base_name(name)
        for lab in self.labels:
            if lab.name == base:
                return lab
        raise DeclarationError(f"world {self.name!r} has no label {base!r} (labels: {', '.join(self.label_names)})")

    def camera(self, name: str) -> Camera:
        for c in self.cameras:
            if c.name == name:
                return c
        raise DeclarationError(f"world {self.name!r} has no camera {name!r}")

    def mode_index(self, mode: str) -> int:
        if mode not in self.modes:
            raise DeclarationError(f"unknown mode {mode!r} for world {self.name!r} "
                                   f"(modes: {', '.join(self.modes) or 'none'})")
        return self.modes.index(mode)

    def mode_list(self, text: str | None, option: str = "--modes") -> tuple[str, ...]:
        """The behavioural modes a comma-separated list names; None gives all the world's. A list that names no
        mode (an empty string, ",") is refused as every other empty list is, not read as all of them."""
        if text is None:
            return self.modes
        names = tuple(m.strip() for m in str(text).split(",") if m.strip())
        if not names:
            raise DeclarationError(f"{option} {text!r} names no mode (leave it out for all: "
                                   f"{', '.join(self.modes) or 'none'})")
        unknown = [m for m in names if m not in self.modes]
        if unknown:
            raise DeclarationError(f"unknown behavioural mode {unknown[0]!r} "
                                   f"(modes: {', '.join(self.modes) or 'none'})")
        return names

    # --- the truth record ----------------------------------------------------------------------------------------
    def pack(self, values: Mapping[str, float] | None = None, /, *, partial: bool = False, **more) -> np.ndarray:
        """The truth record (float64, `truth` order) from a {field: value} mapping and keyword fields; booleans
        become 0/1. Every field must be given unless partial=True (missing ones are NaN)."""
        merged = dict(values or {})
        merged.update(more)
        out = np.full(len(self.truth), np.nan)
        index = self._index
        for name, v in merged.items():
            i = index.get(name)
            if i is None:
                raise DeclarationError(f"world {self.name!r} has no truth field {name!r}")
            out[i] = float(v)
        if not partial and len(merged) < len(self.truth):
            missing = [n for n in self.truth_names if n not in merged]
            raise DeclarationError(f"the truth record of {self.name!r} lacks {', '.join(missing)}")
        return out

    def check_record(self, record) -> np.ndarray:
        """`record` as float64[len(truth)] (a mapping is packed), or DeclarationError."""
        if isinstance(record, Mapping):
            return self.pack(record)
        arr = np.asarray(record, dtype=np.float64)
        if arr.shape != (len(self.truth),):
            raise DeclarationError(f"a truth record of {self.name!r} has {len(self.truth)} values, got shape "
                                   f"{arr.shape}")
        return arr

    def unpack(self, record) -> dict:
        """{field: value}: flags as bool, counts as int, everything else float (NaN stays NaN)."""
        arr = self.check_record(record)
        out: dict[str, bool | int | float] = {}
        for q, v in zip(self.truth, arr.tolist()):
            if q.kind == "bool":
                out[q.name] = bool(v) if v == v else False
            elif q.kind.startswith("i") and v == v:
                out[q.name] = int(round(v))
            else:
                out[q.name] = v
        return out

    def values(self, record, names) -> np.ndarray:
        """The named fields of a record (or of records, last axis) as float64."""
        arr = np.asarray(record, dtype=np.float64)
        return arr[..., [self.index(n) for n in names]]

    # --- labels --------------------------------------------------------------------------------------------------
    def _affine(self, names) -> tuple[np.ndarray, np.ndarray]:
        labs = [self.label(n) for n in names]
        return (np.array([lab.scale for lab in labs], dtype=np.float32),
                np.array([lab.offset for lab in labs], dtype=np.float32))

    def normalise(self, values, names) -> np.ndarray:
        """Label values (last axis ordered as `names`, outputs like "steer+3" welcome) to the training range."""
        names = tuple(names)
        scale, offset = self._affine(names)
        out = np.asarray(values, dtype=np.float32) * scale + offset
        for i, n in enumerate(names):
            clip = self.label(n).clip
            if clip is not None:
                out[..., i] = np.clip(out[..., i], clip[0], clip[1])
        return out

    def denormalise(self, values, names) -> np.ndarray:
        """Inverse of `normalise` (clips aside): network outputs back to the labels' units."""
        scale, offset = self._affine(tuple(names))
        return (np.asarray(values, dtype=np.float32) - offset) / scale

    def normalisation(self, names) -> dict[str, list[float]]:
        """{output: [scale, offset]}, as a checkpoint records it."""
        return {n: [float(self.label(n).scale), float(self.label(n).offset)] for n in names}

    # --- the action ----------------------------------------------------------------------------------------------
    def neutral_action(self) -> np.ndarray:
        return np.array([a.neutral for a in self.action], dtype=np.float64)

    def clip_action(self, action) -> np.ndarray:
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (len(self.action),):
            raise DeclarationError(f"an action of {self.name!r} has {len(self.action)} values "
                                   f"({', '.join(self.action_names)}), got {a.size}")
        lo = np.array([c.low for c in self.action])
        hi = np.array([c.high for c in self.action])
        return np.clip(np.where(np.isfinite(a), a, self.neutral_action()), lo, hi)

    def with_camera(self, name: str, height: int, width: int, inset: str | None = None) -> WorldDeclaration:
        """This declaration with camera `name` rendering height x width (a world configured for other frames), and
        with `inset` composited into its image when given."""
        cams = tuple(Camera(c.name, int(height), int(width), c.channels, c.inset if inset is None else inset)
                     if c.name == name else c for c in self.cameras)
        if cams == self.cameras:
            return self
        self.camera(name)
        return replace(self, cameras=cams)

    def with_column(self, column: Column) -> WorldDeclaration:
        """This declaration with `column` recorded too (a world's optional metadata: the named condition)."""
        if any(c.name == column.name for c in self.columns):
            return self
        return replace(self, columns=self.columns + (column,))

    # --- identity and JSON ---------------------------------------------------------------------------------------
    def to_json(self) -> dict:
        def plain(obj):
            return {f.name: (list(getattr(obj, f.name)) if isinstance(getattr(obj, f.name), tuple)
                             else getattr(obj, f.name)) for f in fields(obj)}

        def camera(c: Camera) -> dict:
            out = plain(c)
            if not c.inset:   # absent unless used: declarations, datasets and fingerprints without one are unchanged
                out.pop("inset")
            return out
        return {"name": self.name, "title": self.title, "dt": self.dt, "version": self.version,
                "cameras": [camera(c) for c in self.cameras], "labels": [plain(x) for x in self.labels],
                "truth": [plain(q) for q in self.truth], "action": [plain(a) for a in self.action],
                "columns": [plain(c) for c in self.columns], "modes": list(self.modes),
                "mode_field": self.mode_field, "moment": {"instants": list(self.moment.instants),
                                                          "horizon": self.moment.horizon},
                "targets": list(self.targets),
                **({"label_sets": {n: list(v) for n, v in self.label_sets}} if self.label_sets else {}),
                **({"observable": list(self.observable)} if self.observable else {}),
                **({"decisive": [[n, b] for n, b in self.decisive]} if self.decisive else {})}

    @classmethod
    def from_json(cls, obj: Mapping) -> WorldDeclaration:
        try:
            def label(d):
                d = dict(d)
                if d.get("clip") is not None:
                    d["clip"] = tuple(d["clip"])
                return Label(**d)
            return cls(name=obj["name"], title=obj.get("title", obj["name"]), dt=float(obj["dt"]),
                       version=int(obj.get("version", 1)),
                       cameras=tuple(Camera(**c) for c in obj["cameras"]),
                       labels=tuple(label(x) for x in obj["labels"]),
                       truth=tuple(Quantity(**q) for q in obj["truth"]),
                       action=tuple(Control(**a) for a in obj["action"]),
                       columns=tuple(Column(**c) for c in obj.get("columns", ())),
                       modes=tuple(obj.get("modes", ())), mode_field=obj.get("mode_field"),
                       moment=Moment(tuple(obj.get("moment", {}).get("instants", (0,))),
                                     int(obj.get("moment", {}).get("horizon", 0))),
                       targets=tuple(obj.get("targets", ())),
                       label_sets=tuple((str(n), tuple(v)) for n, v in dict(obj.get("label_sets", {})).items()),
                       observable=tuple(obj.get("observable", ())),
                       decisive=tuple((str(n), float(b)) for n, b in obj.get("decisive", ())))
        except (KeyError, TypeError, ValueError) as e:
            if isinstance(e, DeclarationError):
                raise
            raise DeclarationError(f"not a world declaration ({type(e).__name__}: {e})") from None

    def fingerprint(self) -> str:
        """A short digest of everything that decides what the data means (titles and prose excluded)."""
        obj = self.to_json()
        obj.pop("title")
        obj.pop("observable", None)   # what an agent may read does not change what recorded data means,
        obj.pop("decisive", None)     # nor which steps a trainer emphasises
        for group in ("cameras", "labels", "truth", "action", "columns"):
            for item in obj[group]:
                item.pop("meaning", None)
        text = json.dumps(obj, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def describe(self) -> str:
        cams = ", ".join(f"{c.name} {c.width}x{c.height}" for c in self.cameras)
        return (f"{self.name} ({self.title}): cameras {cams}; {len(self.labels)} labels; "
                f"action {', '.join(self.action_names)}")
