"""Reading a policy checkpoint file: one :class:`~parcover_env.errors.CheckpointError` naming the file
and what is wrong (empty, corrupt or truncated, another format, another policy's), never torch's traceback.

torch is imported lazily (only when a checkpoint is read).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from parcover_env.errors import CheckpointError

__all__ = ["load_torch_dict", "build_or_explain", "first_line", "as_int", "as_widths", "KNOWN_FORMATS"]

KNOWN_FORMATS: dict[str, tuple[str, ...]] = {
    "bc:PATH (a behaviour-cloned actor)": ("n_in", "n_out", "hidden", "state_dict"),
    "torchrl:PATH (a parcover train policy.pt)": ("obs_dim", "act_dim", "hidden", "state_dict"),
    "a parcover train critic.pt (not a policy)": ("spec", "state_dict"),
}
"""The checkpoint kinds of this package by the keys their dict holds: tells a user who passed
another policy's file which spec reads it."""

_T = TypeVar("_T")


def first_line(exc: BaseException, limit: int = 160) -> str:
    """``Type: first line of the message`` of ``exc``, at most ``limit`` characters (torch's
    messages run over many lines)."""
    message = str(exc)
    if "WeightsUnpickler error:" in message:  # torch's weights-only refusal: the reason, not the advice
        message = message.split("WeightsUnpickler error:", 1)[1].strip().split(". ", 1)[0]
    text = next((line.strip() for line in message.splitlines() if line.strip()), "")
    if len(text) > 100 and ". " in text:  # torch's messages go on with advice after the first sentence
        text = text.split(". ", 1)[0]
    text = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _looks_like(keys: set[str], expected: tuple[str, ...]) -> str:
    for spec, needed in KNOWN_FORMATS.items():
        if set(needed) <= keys and not set(expected) <= set(needed):
            return f"; it looks like {spec}"
    return ""


def load_torch_dict(file: Path, what: str, keys: tuple[str, ...], weights_only: bool) -> dict:
    """The dict saved with ``torch.save`` in ``file`` that holds ``keys``, else CheckpointError:
    ``file`` is empty, not a torch checkpoint (corrupt, truncated, another format, or, with
    ``weights_only``, one holding objects other than tensors), not a dict, or lacks some of ``keys``
    (the message names them and, for another policy's checkpoint, the spec that reads it).
    ``what`` names the expected kind, e.g. ``"TorchRL policy"``."""
    import torch

    file = Path(file)
    try:
        size = file.stat().st_size
    except OSError as exc:
        raise CheckpointError(file, what, f"cannot read it ({exc.strerror or exc})") from None
    if size == 0:
        raise CheckpointError(file, what, "the file is empty (0 bytes)")
    try:
        with warnings.catch_warnings():  # torch warns about some foreign files before it fails on them
            warnings.simplefilter("ignore")
            ckpt = torch.load(file, map_location="cpu", weights_only=weights_only)
    except Exception as exc:  # unpickling a corrupt or foreign file may raise anything (struct.error, ...)
        if weights_only and "Unsupported global" in str(exc):
            problem = (f"it holds Python objects other than tensors ({first_line(exc)}): another program's or "
                       "another policy's file, e.g. a bc: checkpoint (weights-only loading runs no code "
                       "in it)")
        else:
            problem = f"not a torch checkpoint (corrupt, truncated or another format; {first_line(exc)})"
        raise CheckpointError(file, what, problem) from None
    if not isinstance(ckpt, dict):
        raise CheckpointError(file, what, f"it holds a {type(ckpt).__name__}, expected a dict with "
                              f"{', '.join(keys)}")
    missing = [k for k in keys if k not in ckpt]
    if missing:
        found = sorted(str(k) for k in ckpt)
        shown = ", ".join(found[:8]) + (", ..." if len(found) > 8 else "")
        raise CheckpointError(file, what, f"not a {what} checkpoint: no {', '.join(missing)} (it has "
                              f"{shown or 'nothing'}){_looks_like(set(map(str, ckpt)), keys)}")
    return ckpt


def build_or_explain(file: Path, what: str, build: Callable[[], _T]) -> _T:
    """``build()`` (make the network a checkpoint describes and load its weights), or CheckpointError
    naming ``file`` when its fields or weights do not fit (wrong types, shapes or names)."""
    try:
        return build()
    except (TypeError, ValueError, RuntimeError, KeyError, IndexError, AttributeError, OverflowError) as exc:
        raise CheckpointError(file, what, f"its fields or weights do not fit the network it describes "
                              f"({first_line(exc)})") from None


def as_int(value: Any, file: Path, what: str, key: str) -> int:
    """``value`` (the checkpoint's ``key``) as an int >= 1, else CheckpointError."""
    try:
        out = int(value)
    except (TypeError, ValueError, OverflowError):
        raise CheckpointError(file, what, f"{key} must be an integer, got {value!r}"[:200]) from None
    if out < 1 or out != value:
        raise CheckpointError(file, what, f"{key} must be an integer >= 1, got {value!r}"[:200])
    return out


def as_widths(value: Any, file: Path, what: str, key: str = "hidden") -> tuple[int, ...]:
    """``value`` (the checkpoint's hidden layer widths) as a tuple of ints >= 1, else CheckpointError."""
    if isinstance(value, str | bytes) or not hasattr(value, "__iter__"):
        raise CheckpointError(file, what, f"{key} must be a list of layer widths, got {value!r}"[:200])
    return tuple(as_int(v, file, what, key) for v in value)
