"""Thin NumPy wrappers around the torch kernels: each kernel is written once, in torch."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np
import torch


def _to_tensor(x: Any) -> Any:
    if isinstance(x, np.ndarray):
        # torch warns on read-only arrays (Skeleton's, broadcast views); the kernels never write.
        if not x.flags.writeable:
            x = x.copy()
        return torch.from_numpy(np.ascontiguousarray(x))
    if isinstance(x, np.generic):
        return torch.as_tensor(x)
    return x


def _to_numpy(x: Any) -> Any:
    if isinstance(x, torch.Tensor):
        return x.detach().cpu().numpy()
    if isinstance(x, tuple):
        return tuple(_to_numpy(v) for v in x)
    return x


def numpy_kernel(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Wrap a torch function so it takes and returns NumPy arrays (dtype preserved)."""

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        args = tuple(_to_tensor(a) for a in args)
        kwargs = {k: _to_tensor(v) for k, v in kwargs.items()}
        with torch.no_grad():
            return _to_numpy(fn(*args, **kwargs))

    wrapper.__doc__ = f"NumPy wrapper of the torch kernel.\n\n{fn.__doc__ or ''}"
    return wrapper
