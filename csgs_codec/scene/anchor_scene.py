"""Scaffold-GS anchor scenes: anchors on a voxel grid, each spawning K neural Gaussians.

The arrays follow the official Scaffold-GS trainer (github.com/city-super/Scaffold-GS,
``scene/gaussian_model.py`` and ``gaussian_renderer/__init__.py``):

* Gaussian k of anchor i sits at ``positions[i] + offsets[i, k] * exp(scaling[i, :3])``;
* its scale is ``exp(scaling[i, 3:]) * sigmoid(cov_mlp(...)[:3])``;
* opacity (tanh head), color (sigmoid head) and scale/rotation (linear head) come from three
  two-layer MLPs over ``[feature, view direction, (distance), (appearance embedding)]``.

This module holds plain numpy data (no torch); :mod:`csgs_codec.model.scaffold` evaluates it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from csgs_codec.errors import InputError

#: Feature width CSGaussian and HAC use (the official Scaffold-GS default is 32).
DEFAULT_FEAT_DIM = 50
#: Neural Gaussians per anchor (the official default).
DEFAULT_N_OFFSETS = 10
#: Semantic feature width CSGaussian uses.
DEFAULT_SEMANTIC_DIM = 6
#: The three Scaffold-GS heads, their output width per offset and their output activation.
HEADS = {"opacity": (1, "tanh"), "cov": (7, "none"), "color": (3, "sigmoid")}


@dataclass
class MLPWeights:
    """One Scaffold-GS head: ``Linear(D, H) -> ReLU -> Linear(H, O) -> activation``.

    Attributes:
        w1: (H, D) float32 first layer weight (torch ``nn.Linear`` layout: out x in).
        b1: (H,) float32 first layer bias.
        w2: (O, H) float32 second layer weight.
        b2: (O,) float32 second layer bias.
    """

    w1: np.ndarray
    b1: np.ndarray
    w2: np.ndarray
    b2: np.ndarray

    @property
    def in_dim(self) -> int:
        """Input width D."""
        return int(self.w1.shape[1])

    @property
    def out_dim(self) -> int:
        """Output width O."""
        return int(self.w2.shape[0])

    def arrays(self) -> dict[str, np.ndarray]:
        """The four arrays keyed ``w1 b1 w2 b2``."""
        return {"w1": self.w1, "b1": self.b1, "w2": self.w2, "b2": self.b2}

    def validate(self, name: str, source: str | None = None) -> None:
        """Check that the four arrays are float32, finite and chain (H, D) -> (O, H).

        Raises:
            InputError: naming ``name.w1`` etc. as the property.
        """
        for key, arr in self.arrays().items():
            if not isinstance(arr, np.ndarray) or arr.dtype != np.float32:
                raise InputError("expected a float32 array", file=source,
                                 property=f"{name}.{key}")
            if not np.all(np.isfinite(arr)):
                raise InputError("non-finite weight", file=source, property=f"{name}.{key}",
                                 index=int(np.flatnonzero(~np.isfinite(arr.ravel()))[0]))
        h = self.w1.shape[0] if self.w1.ndim == 2 else -1
        o = self.w2.shape[0] if self.w2.ndim == 2 else -1
        expected = {"w1": (h, self.w1.shape[-1]), "b1": (h,), "w2": (o, h), "b2": (o,)}
        for key, shape in expected.items():
            if getattr(self, key).shape != shape or min(shape) <= 0:
                raise InputError(f"shape {getattr(self, key).shape} does not chain with the "
                                 f"other layers (expected {shape})", file=source,
                                 property=f"{name}.{key}")

    def equals(self, other: MLPWeights) -> bool:
        """True when all four arrays match bit for bit."""
        return all(a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()
                   for a, b in zip(self.arrays().values(), other.arrays().values()))


@dataclass
class ScaffoldMLPWeights:
    """The Scaffold-GS MLP weights of one scene (numpy; torch modules are built from them).

    Input layout of every head: ``[feature (F), view direction (3), distance (1 if the head
    uses it)]``, and the color head appends the appearance embedding (A) last, exactly as the
    official renderer concatenates them. Whether a head takes the distance is read from its
    input width.

    Attributes:
        opacity: head with K outputs, tanh; a Gaussian is kept when its value is > 0.
        cov: head with 7K outputs, no activation: per offset 3 scale logits + 4 quaternion.
        color: head with 3K outputs, sigmoid: per offset RGB in [0, 1].
        appearance: optional (C, A) float32 per-training-camera appearance embedding table.
    """

    opacity: MLPWeights
    cov: MLPWeights
    color: MLPWeights
    appearance: np.ndarray | None = None

    def heads(self) -> dict[str, MLPWeights]:
        """The three heads keyed ``opacity cov color``."""
        return {"opacity": self.opacity, "cov": self.cov, "color": self.color}

    @property
    def appearance_dim(self) -> int:
        """Width A of the appearance embedding (0 when there is none)."""
        return 0 if self.appearance is None else int(self.appearance.shape[1])

    def uses_distance(self, head: str, feat_dim: int) -> bool:
        """Whether ``head`` takes the anchor-camera distance as input (for feature width F)."""
        extra = self.appearance_dim if head == "color" else 0
        return self.heads()[head].in_dim - feat_dim - 3 - extra == 1

    def validate(self, feat_dim: int, n_offsets: int, source: str | None = None) -> None:
        """Check every head against the anchors' feature width F and offset count K.

        Raises:
            InputError: naming the head (e.g. ``color.w1``) and what does not fit.
        """
        if self.appearance is not None:
            a = self.appearance
            if (not isinstance(a, np.ndarray) or a.dtype != np.float32 or a.ndim != 2
                    or min(a.shape) <= 0):
                raise InputError("expected a non-empty (C, A) float32 table", file=source,
                                 property="appearance")
            if not np.all(np.isfinite(a)):
                raise InputError("non-finite value", file=source, property="appearance")
        for name, weights in self.heads().items():
            weights.validate(name, source)
            per_offset = HEADS[name][0]
            if weights.out_dim != per_offset * n_offsets:
                raise InputError(f"{weights.out_dim} outputs, expected {per_offset} x "
                                 f"{n_offsets} offsets", file=source, property=f"{name}.w2")
            extra = weights.in_dim - feat_dim - 3 - (self.appearance_dim if name == "color"
                                                     else 0)
            if extra not in (0, 1):
                raise InputError(f"{weights.in_dim} inputs do not match feature width "
                                 f"{feat_dim} + view direction 3 (+ distance 1)"
                                 + (f" + appearance {self.appearance_dim}"
                                    if name == "color" else ""),
                                 file=source, property=f"{name}.w1")

    def equals(self, other: ScaffoldMLPWeights | None) -> bool:
        """True when all weights match bit for bit."""
        if not isinstance(other, ScaffoldMLPWeights):
            return False
        if (self.appearance is None) != (other.appearance is None):
            return False
        if self.appearance is not None and (
                self.appearance.shape != other.appearance.shape
                or self.appearance.tobytes() != other.appearance.tobytes()):
            return False
        return all(a.equals(b) for a, b in zip(self.heads().values(), other.heads().values()))


@dataclass
class AnchorScene:
    """A Scaffold-GS scene: M anchors, each with K offsets, plus the MLPs that decode them.

    Attributes:
        positions: (M, 3) float32 anchor centres, world units.
        features: (M, F) float32 anchor features (F = 50 in CSGaussian/HAC).
        offsets: (M, K, 3) float32 Gaussian offsets in units of ``exp(scaling[:, :3])``.
        scaling: (M, 6) float32 natural-log scales as Scaffold-GS stores them; the activation
            is ``exp``: ``exp(scaling[:, :3])`` scales the offsets, ``exp(scaling[:, 3:])`` is
            the base scale of the Gaussians.
        offset_mask: (M, K) bool, True where the offset is kept; masked offsets spawn nothing.
        semantic: optional (M, S) float32 semantic feature shared by an anchor's Gaussians.
        semantic_names: names of the S semantic channels (PLY property names, ``sem_*``).
        labels: optional (M,) int32 object labels.
        mlps: the Scaffold-GS MLP weights, or None for anchors without a decoder.
        view_origins: optional (V, 3) float32 points the scene was trained to be seen from
            (the training cameras' centres, world units), used to bake it into a standard
            scene; .csgs files carry up to 32 of them (``vorg``).
    """

    positions: np.ndarray
    features: np.ndarray
    offsets: np.ndarray
    scaling: np.ndarray
    offset_mask: np.ndarray
    semantic: np.ndarray | None = None
    semantic_names: tuple[str, ...] = field(default_factory=tuple)
    labels: np.ndarray | None = None
    mlps: ScaffoldMLPWeights | None = None
    view_origins: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.positions.shape[0])

    @property
    def count(self) -> int:
        """Number of anchors M."""
        return len(self)

    @property
    def feat_dim(self) -> int:
        """Feature width F."""
        return int(self.features.shape[1])

    @property
    def n_offsets(self) -> int:
        """Offsets per anchor K."""
        return int(self.offsets.shape[1])

    def active_offsets(self) -> int:
        """Number of unmasked offsets (an upper bound on the neural Gaussians of any view)."""
        return int(np.count_nonzero(self.offset_mask))

    def gaussian_positions(self) -> np.ndarray:
        """(M, K, 3) float32 Gaussian centres ``x + O_k * exp(l[:3])``, masked ones included."""
        step = np.exp(self.scaling[:, :3].astype(np.float32))
        return self.positions[:, None, :] + self.offsets * step[:, None, :]

    def subset(self, keep: np.ndarray) -> AnchorScene:
        """A new scene with the anchors selected by ``keep`` ((M,) bool mask or index array)."""
        return AnchorScene(
            positions=self.positions[keep], features=self.features[keep],
            offsets=self.offsets[keep], scaling=self.scaling[keep],
            offset_mask=self.offset_mask[keep],
            semantic=None if self.semantic is None else self.semantic[keep],
            semantic_names=self.semantic_names,
            labels=None if self.labels is None else self.labels[keep], mlps=self.mlps,
            view_origins=self.view_origins)

    def equals(self, other: AnchorScene) -> bool:
        """True when every array, the semantic names and the MLP weights match bit for bit."""
        if not isinstance(other, AnchorScene) or self.semantic_names != other.semantic_names:
            return False
        for name in ("positions", "features", "offsets", "scaling", "offset_mask", "semantic",
                     "labels", "view_origins"):
            a, b = getattr(self, name), getattr(other, name)
            if (a is None) != (b is None):
                return False
            if a is not None and (a.shape != b.shape or a.dtype != b.dtype
                                  or a.tobytes() != b.tobytes()):
                return False
        if (self.mlps is None) != (other.mlps is None):
            return False
        return self.mlps is None or self.mlps.equals(other.mlps)

    def validate(self, source: str | None = None) -> None:
        """Check shapes, dtypes, finiteness and the MLPs against F and K.

        Raises:
            InputError: naming the property and, for values, the first bad anchor index.
        """
        for name in ("positions", "features", "offsets", "scaling", "offset_mask",
                     "semantic", "labels"):
            value = getattr(self, name)
            if not isinstance(value, np.ndarray) and not (value is None and name in (
                    "semantic", "labels")):
                raise InputError(f"expected a numpy array, got {type(value).__name__}",
                                 file=source, property=name)
        p = self.positions
        if p.ndim != 2 or p.shape[1:] != (3,):
            raise InputError(f"expected shape (M, 3), got {p.shape}", file=source,
                             property="positions")
        m = p.shape[0]
        f = self.features.shape[1] if self.features.ndim == 2 else -1
        k = self.offsets.shape[1] if self.offsets.ndim == 3 else -1
        expected = {
            "positions": ((m, 3), np.float32),
            "features": ((m, f), np.float32),
            "offsets": ((m, k, 3), np.float32),
            "scaling": ((m, 6), np.float32),
            "offset_mask": ((m, k), np.bool_),
        }
        for name, (shape, dtype) in expected.items():
            arr = getattr(self, name)
            if arr.shape != shape or min(shape) < 0:
                raise InputError(f"expected shape {shape}, got {arr.shape}", file=source,
                                 property=name)
            if arr.dtype != dtype:
                raise InputError(f"expected dtype {np.dtype(dtype)}, got {arr.dtype}",
                                 file=source, property=name)
        if f == 0 or k == 0:
            raise InputError("feature width and offset count must be positive", file=source,
                             property="features" if f == 0 else "offsets")
        if self.semantic is not None:
            s = self.semantic
            if s.ndim != 2 or s.shape[0] != m or s.dtype != np.float32:
                raise InputError(f"expected (M, S) float32, got {s.shape} {s.dtype}",
                                 file=source, property="semantic")
            if len(self.semantic_names) != s.shape[1]:
                raise InputError(f"{s.shape[1]} channels but {len(self.semantic_names)} names",
                                 file=source, property="semantic")
        if self.labels is not None and (self.labels.shape != (m,)
                                        or self.labels.dtype != np.int32):
            raise InputError(f"expected (M,) int32, got {self.labels.shape} "
                             f"{self.labels.dtype}", file=source, property="labels")
        for name in ("positions", "features", "offsets", "scaling", "semantic"):
            values = getattr(self, name)
            if values is None or values.size == 0:
                continue
            bad = ~np.isfinite(values.reshape(m, -1)).all(axis=1)
            if bad.any():
                raise InputError("non-finite value", file=source, property=name,
                                 index=int(np.flatnonzero(bad)[0]))
        if self.view_origins is not None:
            v = self.view_origins
            if (not isinstance(v, np.ndarray) or v.ndim != 2 or v.shape[1:] != (3,)
                    or v.dtype != np.float32 or len(v) == 0):
                raise InputError("expected a non-empty (V, 3) float32 array", file=source,
                                 property="view_origins")
            if not np.all(np.isfinite(v)):
                raise InputError("non-finite value", file=source, property="view_origins")
        if self.mlps is not None:
            self.mlps.validate(f, k, source)


def default_semantic_names(count: int) -> tuple[str, ...]:
    """``("sem_0", ..., "sem_{count-1}")``: PLY names the standard reader keeps as semantic."""
    return tuple(f"sem_{i}" for i in range(count))
