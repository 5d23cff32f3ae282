"""Reading and writing agent checkpoints: safetensors tensors with JSON metadata (never pickle)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from safetensors import SafetensorError
from safetensors.numpy import load_file, save_file

FORMAT = "fleetrl.agent/1"
"""value of the ``format`` metadata key in every checkpoint this module writes"""


class CheckpointError(ValueError):
    """A checkpoint file that cannot be used: unreadable, not an agent, or for another architecture."""


def write_checkpoint(path: str | Path, tensors: dict[str, np.ndarray], metadata: dict[str, Any]) -> None:
    """Write ``tensors`` and ``metadata`` (stored as one JSON string under ``fleetrl``) to ``path``.

    The file is written beside the target and renamed into place, so a crash never leaves half a model.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    header = {"format": FORMAT, "fleetrl": json.dumps(metadata, sort_keys=True)}
    contiguous = {name: np.ascontiguousarray(t) for name, t in tensors.items()}
    partial = target.with_name(target.name + ".partial")
    save_file(contiguous, str(partial), metadata=header)
    partial.replace(target)


def read_checkpoint(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Tensors and metadata of a checkpoint written by :func:`write_checkpoint`.

    :raises FileNotFoundError: no file at ``path``
    :raises CheckpointError: the file is not a readable safetensors file or not a fleetrl agent
    """
    source = Path(path)
    if not source.is_file():
        raise FileNotFoundError(f"no model file at {source}")
    try:
        tensors = load_file(str(source))
        with open(source, "rb") as handle:
            header_len = int.from_bytes(handle.read(8), "little")
            header = json.loads(handle.read(header_len))
    except (SafetensorError, OSError, ValueError) as exc:
        raise CheckpointError(f"{source} is not a readable safetensors model file ({exc})") from exc
    raw = header.get("__metadata__") or {}
    if raw.get("format") != FORMAT or "fleetrl" not in raw:
        raise CheckpointError(
            f"{source} is a safetensors file but not a fleetrl agent model (format {FORMAT})"
        )
    try:
        metadata = json.loads(raw["fleetrl"])
    except json.JSONDecodeError as exc:
        raise CheckpointError(f"{source} has unreadable fleetrl metadata ({exc})") from exc
    if not isinstance(metadata, dict):
        raise CheckpointError(f"{source} has fleetrl metadata that is not a JSON object")
    return tensors, metadata


def check_tensors_fit(
    tensors: dict[str, np.ndarray], shapes: dict[str, tuple[int, ...]], source: str
) -> None:
    """Refuse ``tensors`` unless they are exactly the named ``shapes`` (no tensor missing, none extra).

    :raises CheckpointError: naming every missing, unexpected or wrongly shaped tensor of ``source``
    """
    problems = [f"missing {k}" for k in shapes if k not in tensors]
    problems += [f"unexpected {k}" for k in tensors if k not in shapes]
    problems += [
        f"{k} has shape {tuple(tensors[k].shape)}, expected {shape}"
        for k, shape in shapes.items()
        if k in tensors and tuple(tensors[k].shape) != shape
    ]
    if problems:
        raise CheckpointError(f"{source} does not fit this architecture: " + "; ".join(problems))


def check_architecture(path: str | Path, arch: dict[str, Any], wanted: dict[str, int | None]) -> None:
    """CheckpointError unless the model file at ``path`` (architecture ``arch``) has every value ``wanted``
    asks for (None: any)."""
    for key, want in wanted.items():
        if want is not None and want != arch[key]:
            raise CheckpointError(
                f"{path} is a model for {key}={arch[key]}, but {want} is needed here "
                "(a model trained for another environment or architecture)"
            )
