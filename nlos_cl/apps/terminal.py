"""What `nlos-cl` prints besides its answer: Python warnings as one line each,
`nlos-cl: warning: ...`, every distinct warning once per run and without Python's source line;
and --verbose (the OpenCL compiler's output, which nlos_cl.device.runtime otherwise keeps off the
terminal); and how the command leaves (`leave`, after nlos_cl.apps.console.run). Only the command line changes how warnings look: the library keeps Python's standard
warnings, so a program that imports nlos_cl filters and formats them as it likes.
"""
from __future__ import annotations

import argparse
import functools
import os
import sys
import warnings

VERBOSE_HELP = ("show the OpenCL compiler's output (otherwise kept off the terminal unless a "
                "build fails); the library reads NLOS_CL_VERBOSE=1")


class _Verbose(argparse.Action):
    """--verbose: sets NLOS_CL_VERBOSE=1 as it is parsed, for the library and any worker it
    starts (one_run puts the variable back afterwards)."""

    def __init__(self, option_strings, dest, default=None, **kw):
        super().__init__(option_strings, dest, nargs=0, default=default, **kw)

    def __call__(self, parser, namespace, values, option_string=None):
        os.environ["NLOS_CL_VERBOSE"] = "1"
        setattr(namespace, self.dest, True)


def verbose_flag() -> argparse.ArgumentParser:
    """A parent parser holding --verbose, for the top-level parser and each command alike, so
    `nlos-cl --verbose locate F` and `nlos-cl locate F --verbose` both work."""
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument("--verbose", action=_Verbose, default=argparse.SUPPRESS,
                        help=VERBOSE_HELP)
    return parent


def one_line(message) -> str:
    """A warning's text on one line: a multi-line message's lines joined by single spaces."""
    return " ".join(str(message).split())


def one_run(main):
    """Wrap the CLI's main: while it runs, warnings print as `nlos-cl: warning: <text>`, each
    distinct text once; afterwards Python's warnings and NLOS_CL_VERBOSE are as they were, so
    calling cli.main() in-process leaves the caller untouched."""
    @functools.wraps(main)
    def run(*args, **kw):
        seen: set[str] = set()

        def show(message, category, filename, lineno, file=None, line=None):
            text = one_line(message)
            if text not in seen:
                seen.add(text)
                print(f"nlos-cl: warning: {text}", file=file or sys.stderr, flush=True)

        shown, env_before = warnings.showwarning, os.environ.get("NLOS_CL_VERBOSE")
        warnings.showwarning = show
        try:
            return main(*args, **kw)
        finally:
            warnings.showwarning = shown
            if env_before is None:
                os.environ.pop("NLOS_CL_VERBOSE", None)
            else:
                os.environ["NLOS_CL_VERBOSE"] = env_before
    return run


def leave(code) -> None:
    """Exit with main's `code`, quickly. When main returns, every output is written and closed;
    what Python's shutdown would still do is tear down the OpenCL runtime and every module,
    ~30 ms of a one-shot `locate`'s ~380 (nlos_cl/apps/bench/analysis.md). So
    the atexit handlers run (temporary folders, logging, coverage), then stdout and stderr are
    flushed, and the process leaves with os._exit, unless another Python thread is alive (then
    the usual shutdown waits for it) or a flush fails (then Python reports it as usual; a
    reader that left, `| head`, quietly)."""
    import atexit
    import threading
    if threading.active_count() > 1:
        sys.exit(code)
    atexit._run_exitfuncs()  # first: what they print is flushed below
    try:
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:  # None: started with the stream closed (`>&-`)
                stream.flush()
    except BrokenPipeError:  # the reader left: no "Exception ignored" at shutdown either
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        os._exit(code or 1)
    except (OSError, ValueError):
        sys.exit(code)
    os._exit(code or 0)


STAGE_CHARS = 60  # of the library's stage on the progress line


class Elapsed:
    """`with Elapsed("locating"):` a line on a terminal's stderr that counts the seconds of work
    that lasts longer than `after_s` (a model fit on thousands of histograms takes minutes)
    and says what the library is doing (core.progress: "model fit: closed shapes ..."),
    updated once a second from a thread and cleared at the end; nothing where stderr is not a
    terminal (pipes, logs, tests)."""

    def __init__(self, what: str, after_s: float = 2.0, stream=None):
        self.what, self.after_s = what, after_s
        self.stream = sys.stderr if stream is None else stream
        self._stop, self._thread = None, None

    def __enter__(self):
        import threading
        if not getattr(self.stream, "isatty", lambda: False)():
            return self
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._tick, daemon=True)
        self._thread.start()
        return self

    def _tick(self) -> None:
        import time

        from ..core.progress import current
        start, shown = time.monotonic(), False
        while not self._stop.wait(self.after_s if not shown else 1.0):
            shown = True
            doing = current()  # the library's stage (core.progress), cut to one line
            doing = f" - {doing[:STAGE_CHARS]}" if doing else ""
            self.stream.write(f"\r{self.what}: {time.monotonic() - start:.0f} s{doing}\033[K")
            self.stream.flush()
        if shown:
            self.stream.write("\r\033[K")
            self.stream.flush()

    def __exit__(self, *exc):
        if self._thread is not None:
            self._stop.set()
            self._thread.join()
        return False
