"""Stage-1 checkpoints: save a :class:`ColorStageState` and continue it bit for bit.

A checkpoint is one ``torch.save`` file of plain containers and tensors (so it loads with
``weights_only=True``: opening a checkpoint never runs code from it): the settings, the anchor
grid and cells, every state dict (model, rate model, both optimisers), the random generators'
states, the remaining view order, the growth statistics, the loss history and the step. Files
are written atomically; :func:`load_checkpoint` refuses a file that is not a checkpoint of this
format with an InputError naming it.
"""

from __future__ import annotations

import dataclasses
import io
import warnings
from pathlib import Path

import numpy as np
import torch

from csgs_codec.atomic_write import write_atomically
from csgs_codec.errors import CsgsWarning, InputError
from csgs_codec.train.anchor_growth import GrowthStats
from csgs_codec.train.anchor_model import AnchorGrid, AnchorModel
from csgs_codec.train.anchor_rate import AnchorRateModel
from csgs_codec.train.color_stage import ColorStageSettings, ColorStageState, make_optimizers

#: Format tag stored in every checkpoint.
CHECKPOINT_FORMAT = "csgs-train-checkpoint/3"
#: Earlier formats, named in the error that refuses them (/3 holds the rate model's CARM as
#: one masked network).
EARLIER_FORMATS = ("csgs-train-checkpoint/1", "csgs-train-checkpoint/2")


def save_checkpoint(state: ColorStageState, path: str | Path) -> None:
    """Write ``state`` to ``path`` atomically."""
    settings = dataclasses.asdict(state.settings)
    settings["background"] = list(settings["background"])
    stats = state.stats
    document = {
        "format": CHECKPOINT_FORMAT,
        "settings": settings,
        "step": state.step,
        "grid_origin": torch.as_tensor(np.asarray(state.model.grid.origin, np.float64),
                                       device="cpu"),  # cpu: checkpoints hold CPU tensors
        "grid_voxel": float(state.model.grid.voxel),
        "model": {k: v.detach().cpu() for k, v in state.model.state_dict().items()},
        "rate_model": {k: v.detach().cpu() for k, v in state.rate_model.state_dict().items()},
        "anchor_optimizer": state.anchor_optimizer.state_dict(),
        "shared_optimizer": state.shared_optimizer.state_dict(),
        "view_generator": state.view_generator.get_state(),
        "anchor_generator": state.model.generator.get_state(),
        "view_names": list(state.view_names),
        "bad_run": state.bad_run,
        "noise_generator": state.noise_generator.get_state(),
        "order": list(state.order),
        "stats": None if stats is None else {f.name: getattr(stats, f.name)
                                             for f in dataclasses.fields(stats)},
        "history": {k: list(v) for k, v in state.history.items()},
        "skipped_steps": state.skipped_steps,
        "seconds": state.seconds,
    }
    buffer = io.BytesIO()
    torch.save(document, buffer)
    write_atomically(path, buffer.getvalue())


def load_checkpoint(path: str | Path, device: str | None = None) -> ColorStageState:
    """The :class:`ColorStageState` saved at ``path``, ready to continue training.

    Args:
        path: the checkpoint file.
        device: torch device to continue on (default: the one it was saved from); a run
            checkpointed on a GPU can continue on the CPU and the other way round.

    Raises:
        InputError: a missing, unreadable or foreign file, naming it.
    """
    path = Path(path)
    try:
        document = torch.load(path, map_location="cpu", weights_only=True)
    except FileNotFoundError:
        raise InputError("no such checkpoint", file=path) from None
    except Exception as error:  # torch raises many kinds for a damaged or foreign file
        raise InputError(f"not a readable checkpoint: {type(error).__name__}",
                         file=path) from None
    if isinstance(document, dict) and document.get("format") in EARLIER_FORMATS:
        raise InputError(f"a {document['format']} checkpoint from an earlier version; this "
                         f"version continues {CHECKPOINT_FORMAT} only: start the stage again",
                         file=path)
    if not isinstance(document, dict) or document.get("format") != CHECKPOINT_FORMAT:
        raise InputError(f"not a {CHECKPOINT_FORMAT} file", file=path)
    try:
        return _state_from(document, device)
    except InputError as error:
        raise InputError(f"checkpoint settings: {error.message}", file=path) from None
    except Exception as error:  # any malformed field: the file is not what it claims
        raise InputError(f"damaged checkpoint: {type(error).__name__}: {error}",
                         file=path) from None


def _state_from(document: dict, device: str | None) -> ColorStageState:
    fields = {f.name for f in dataclasses.fields(ColorStageSettings)}
    values = {k: v for k, v in document["settings"].items() if k in fields}
    values["background"] = tuple(values["background"])
    if device is not None:
        values["device"] = device
    settings = ColorStageSettings(**values)
    settings.validate()
    grid = AnchorGrid(document["grid_origin"].numpy(), float(document["grid_voxel"]))
    weights = document["model"]
    model = AnchorModel(weights["cells"].numpy(), grid, feat_dim=settings.feat_dim,
                        n_offsets=settings.n_offsets, seed=settings.seed,
                        device=settings.device)
    model.load_state_dict(weights)
    rate_model = AnchorRateModel(settings.feat_dim, settings.n_offsets, settings.steps(),
                                 device=settings.device)
    rate_model.load_state_dict(document["rate_model"])
    state = ColorStageState(model, rate_model, settings, step=int(document["step"]))
    make_optimizers(state)
    state.anchor_optimizer.load_state_dict(document["anchor_optimizer"])
    state.shared_optimizer.load_state_dict(document["shared_optimizer"])
    state.view_generator.set_state(document["view_generator"])
    state.model.generator.set_state(document["anchor_generator"])
    state.view_names = [str(name) for name in document["view_names"]]
    state.bad_run = int(document["bad_run"])
    noise_state = document["noise_generator"]
    state.noise_generator = torch.Generator(device=settings.device)
    if noise_state.numel() == state.noise_generator.get_state().numel():
        state.noise_generator.set_state(noise_state)
    else:  # saved on another kind of device: its generator state does not carry over
        state.noise_generator.manual_seed(settings.seed + 2 + state.step)
        warnings.warn(f"the checkpoint's noise generator belongs to another kind of device "
                      f"than {settings.device}: training continues with a fresh one, so the "
                      "result will differ from an uninterrupted run", CsgsWarning,
                      stacklevel=3)
    state.order = [int(i) for i in document["order"]]
    if document["stats"] is not None:
        state.stats = GrowthStats(**document["stats"])
    state.history = {k: list(v) for k, v in document["history"].items()}
    state.skipped_steps = int(document["skipped_steps"])
    state.seconds = float(document["seconds"])
    return state
