"""Progress output of funcorr's long calls (``progress=`` of :func:`funcorr.match`,
:func:`funcorr.prepare`, :func:`funcorr.geodesic_all_pairs`, :func:`funcorr.batch.match_pairs`).

``progress`` is one of:

* ``None`` (default): a bar when someone is watching (stderr is a terminal, or the code runs in a
  Jupyter / VS Code notebook), nothing otherwise (scripts whose stderr goes to a file or a pipe,
  tests); ``$FUNCORR_PROGRESS=0`` (or ``1``) turns it off (or on) for the whole process;
* ``False``: nothing; ``True``: a bar even when stderr is not a terminal;
* a callable ``progress(stage, done, total)``: called about every 50 ms with the computation's
  stage (``"eigenbasis"``, ``"zoomout"``, ...) and, when the stage counts its steps, ``done`` of
  ``total`` (``total`` 0 otherwise).

The bar is ``tqdm.auto``'s when tqdm is installed (a widget in notebooks), else one line on
stderr redrawn in place; it appears only once a call has run for half a second, and is removed
when the call ends. The computation itself runs with the GIL released: the calling thread waits,
draws the bar and runs Python's signal handlers, so Ctrl-C stops the call (KeyboardInterrupt)
within a fraction of a second.
"""

from __future__ import annotations

import os as _os
import sys as _sys
import time as _time

DELAY = 0.5  # seconds before a bar appears: quick calls stay silent
REDRAW = 0.2  # seconds between redraws of an unchanged bar (elapsed time)


def _env_setting():
    value = _os.environ.get("FUNCORR_PROGRESS", "").strip().lower()
    if value in ("0", "false", "no", "off"):
        return False
    if value in ("1", "true", "yes", "on"):
        return True
    return None


def in_notebook() -> bool:
    """Whether the code runs in a Jupyter kernel (Jupyter, VS Code notebooks)."""
    ipython = _sys.modules.get("IPython")
    if ipython is None:
        return False
    try:
        shell = ipython.get_ipython()
    except Exception:
        return False
    return shell is not None and type(shell).__name__ == "ZMQInteractiveShell"


def _stderr_is_terminal() -> bool:
    try:
        return _sys.stderr is not None and _sys.stderr.isatty()
    except Exception:
        return False


def wanted(progress) -> bool:
    """Whether ``progress`` (None, True or False) asks for a bar."""
    if progress is None:
        env = _env_setting()
        if env is not None:
            return env
        return in_notebook() or _stderr_is_terminal()
    return bool(progress)


def reporter(progress, what: str):
    """The reporter for ``progress`` (see the module docs) of the call ``what``: a callable
    ``(stage, done, total)`` with a ``close()`` method, or None for no output. ValueError for
    anything else than None, a bool or a callable."""
    if progress is not None and not isinstance(progress, bool):
        if callable(progress):
            return _Callback(progress)
        raise ValueError(f"progress: expected None, True, False or a callable (stage, done, total), got {progress!r}")
    return Bar(what) if wanted(progress) else None


class _Callback:
    def __init__(self, f):
        self.f = f

    def __call__(self, stage: str, done: int, total: int) -> None:
        self.f(stage, done, total)

    def close(self) -> None:
        pass


class Bar:
    """A progress bar of one call (tqdm.auto's when available, else a line on stderr), drawn
    from ``(stage, done, total)`` updates; removed by ``close()``."""

    def __init__(self, what: str):
        self.what = what
        self.start = _time.monotonic()
        self.last_draw = 0.0
        self.state = None
        self.tqdm = None
        self.line = False  # the stderr line is drawn
        self.width = 0  # of the stderr line drawn last
        self.printed_stage = None  # the stage printed last (not a terminal)
        self.closed = False

    def __call__(self, stage: str, done: int, total: int) -> None:
        now = _time.monotonic()
        if self.closed or now - self.start < DELAY:
            return
        state = (stage, done, total)
        if state == self.state and now - self.last_draw < REDRAW:
            return
        self.state, self.last_draw = state, now
        try:
            self._draw(stage, done, total, now)
        except Exception:
            self.closed = True  # a broken stream: no more output, the call goes on

    def _draw(self, stage: str, done: int, total: int, now: float) -> None:
        desc = f"{self.what}: {stage}" if stage else self.what
        if self.tqdm is None and not self.line:
            self.tqdm = _new_tqdm(desc)
        if self.tqdm is not None:
            bar = self.tqdm
            if total > 0:
                bar.bar_format = "{desc}: {percentage:3.0f}%|{bar}| {n_fmt}/{total_fmt} [{elapsed}]"
                bar.total = total
                bar.n = min(done, total)
            else:
                bar.bar_format = "{desc} [{elapsed}]"
                bar.total = None
                bar.n = 0
            bar.set_description_str(desc, refresh=False)
            bar.refresh()
            return
        self.line = True
        steps = f" {done}/{total}" if total > 0 else ""
        text = f"{desc}{steps} [{now - self.start:.0f} s]"
        stream = _sys.stderr
        if _stderr_is_terminal() or in_notebook():
            stream.write("\r" + text.ljust(self.width))
            self.width = len(text)
        elif stage != self.printed_stage:
            stream.write(text + "\n")  # a file or a pipe: one line per stage
            self.printed_stage = stage
        stream.flush()

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        try:
            if self.tqdm is not None:
                self.tqdm.close()
            elif self.line and (_stderr_is_terminal() or in_notebook()):
                _sys.stderr.write("\r" + " " * self.width + "\r")
                _sys.stderr.flush()
        except Exception:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _new_tqdm(desc: str):
    """A tqdm.auto bar on stderr that disappears when closed, or None without tqdm."""
    try:
        import warnings

        with warnings.catch_warnings():
            # In a notebook without ipywidgets tqdm.auto warns and falls back to its text bar,
            # which notebooks draw well enough.
            warnings.simplefilter("ignore")
            from tqdm.auto import tqdm
    except Exception:
        return None
    try:
        return tqdm(total=None, desc=desc, file=_sys.stderr, leave=False, dynamic_ncols=True, bar_format="{desc} [{elapsed}]")
    except Exception:
        return None


class reporting:
    """``with reporting(progress, what) as report:`` the reporter of :func:`reporter` (None for no
    output), closed on leaving the block, also by an exception (KeyboardInterrupt)."""

    def __init__(self, progress, what: str):
        self.report = reporter(progress, what)

    def __enter__(self):
        return self.report

    def __exit__(self, *exc) -> None:
        if self.report is not None:
            self.report.close()
