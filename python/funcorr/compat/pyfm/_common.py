"""What the modules of ``funcorr.compat.pyfm`` share: the warning class and its once-only rule."""

from __future__ import annotations

import warnings as _warnings


class FuncorrCompatWarning(UserWarning):
    """Something of pyFM that ``funcorr.compat.pyfm`` does differently (or not at all): said once
    per difference and process, never silently ignored."""


_said: set = set()


def warn_once(key: str, message: str, stacklevel: int = 3) -> None:
    """Warns with ``message`` the first time ``key`` comes up in this process."""
    if key in _said:
        return
    _said.add(key)
    _warnings.warn(message, FuncorrCompatWarning, stacklevel=stacklevel)
