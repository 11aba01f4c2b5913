"""The error and exit conventions every subcommand of ``lfjax`` follows, and the one guard
(:func:`guarded`) its work runs under. The flags are declared in :mod:`lfjax.cli.flags`,
the compilation cache in :mod:`lfjax.cli.cache`.

Conventions: a usage error (a flag argparse refuses, or a value a library check refuses
before any work) prints one line and exits with status 2; a failure during the run prints
one line and exits with status 1 (``LFJAX_DEBUG=1`` lets the exception through); Ctrl-C
exits with status 130. A library check raises :class:`~lfjax.base.errors.ParameterError`
naming its parameter; :func:`refuse` names the flag instead, through
:data:`lfjax.cli.flags.FLAGS`.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from collections.abc import Callable
from typing import TypeVar

from lfjax.base.errors import ParameterError
from lfjax.base.files import emergency_cleanup
from lfjax.cli.flags import FLAGS

PROG = "lfjax"

T = TypeVar("T")

def message(err: BaseException, command: str | None = None, fold: bool = False) -> str:
    """``err``'s message; a :class:`ParameterError` names the flags of ``command``
    (:data:`~lfjax.cli.flags.FLAGS`). ``fold``: whitespace folded into one line (a list of problems, such as
    a sweep config's, keeps its lines otherwise)."""
    text = err.naming(FLAGS.get(command, {})) if isinstance(err, ParameterError) else str(err)
    return " ".join(text.split()) if fold else text


def refuse(prog: str, err: BaseException | str, command: str | None = None,
           fold: bool = False) -> int:
    """A value refused before any work (a usage error): said on stderr; exit status 2."""
    text = err if isinstance(err, str) else message(err, command, fold)
    print(f"{prog}: error: {text}", file=sys.stderr)
    return 2


def interrupted(prog: str, note: str = "") -> int:
    """Ctrl-C: one line on stderr; exit status 130."""
    print(f"{prog}: interrupted{note}", file=sys.stderr)
    return 130


INTERRUPT_GRACE_S = 1.5
"""Seconds a Ctrl-C'd run has to stop through its own clean-up (each ``except
KeyboardInterrupt`` and ``finally``: staging folders removed, locks released) before
:func:`exit_promptly_on_interrupt` ends it: a main thread inside a long XLA computation sees
the KeyboardInterrupt only when that computation returns."""

_STOPPED = threading.Event()  # the run has done its clean-up and is exiting


def exit_promptly_on_interrupt(prog: str, grace_s: float = INTERRUPT_GRACE_S) -> bool:
    """Make Ctrl-C (SIGINT) and SIGTERM end this process within ``grace_s`` seconds.

    Python runs its SIGINT handler (raising KeyboardInterrupt) only between bytecodes of the
    main thread, so a Ctrl-C during a compiled computation waited for it to finish. The C
    signal handler writes the signal to a wake-up pipe at once, though: a watcher thread
    reads it and, unless the main thread has finished its own clean-up within ``grace_s``
    (:func:`exit_now`), removes this process's unfinished outputs (the staging folders of
    :func:`lfjax.base.files.staged_output`) and releases its store locks
    (:func:`lfjax.base.files.emergency_cleanup`), says so, and exits with status 130. Only in
    the main thread of the real command (not when :func:`lfjax.cli.main` is called with
    ``argv``, as tests do); returns whether it was installed."""
    if threading.current_thread() is not threading.main_thread():
        return False
    if callable(signal.getsignal(signal.SIGINT)):
        # Python's own handler again (lfjax's start-up one exits at once, cleaning nothing)
        signal.signal(signal.SIGINT, signal.default_int_handler)
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    try:
        signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)
    except ValueError:
        return False
    stop_signals = {int(signal.SIGINT), int(signal.SIGTERM)}

    def watch() -> None:
        while True:
            try:
                received = os.read(read_end, 64)
            except OSError:
                return
            if not received:
                return
            if stop_signals.intersection(received) and not _STOPPED.wait(grace_s):
                emergency_cleanup()  # staging folders removed, store locks released
                print(f"{prog}: interrupted (stopped after {grace_s:g} s without waiting for "
                      f"the computation; unfinished outputs removed)", file=sys.stderr,
                      flush=True)
                os._exit(130)

    threading.Thread(target=watch, name="lfjax-interrupt-watch", daemon=True).start()
    previous_hook = sys.unraisablehook

    def unraisable(info) -> None:
        # a KeyboardInterrupt raised inside a garbage-collection callback (XLA's) is lost to
        # the main thread: the watcher ends the run, without a traceback on the way
        if info.exc_type is not None and issubclass(info.exc_type, KeyboardInterrupt):
            return
        previous_hook(info)

    sys.unraisablehook = unraisable
    return True


def exit_now(status: int) -> None:
    """End the real command with ``status`` once its clean-up is done, without the
    interpreter's shutdown: after a Ctrl-C, XLA's worker threads may still be running a
    computation, and tearing the runtime down under them crashed the process (a
    segmentation fault, exit -11, instead of 130). Output streams are flushed first."""
    _STOPPED.set()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(status)


def unexpected_error(prog: str, err: Exception, suffix: str = "") -> int:
    """An error no check foresaw: one line on stderr, no traceback (``LFJAX_DEBUG=1``
    re-raises it); exit status 1."""
    text = " ".join(str(err).split()) or type(err).__name__
    print(f"{prog}: error: {type(err).__name__}: {text}{suffix}", file=sys.stderr)
    if os.environ.get("LFJAX_DEBUG"):
        raise err
    return 1


def guarded(prog: str, command: str | None, work: Callable[[], T], *,
            note: str | Callable[[], str] = "", refused: tuple[type[Exception], ...] = (ValueError,),
            fold: bool = False,
            failed: Callable[[Exception], str | None] | None = None) -> tuple[T | None, int | None]:
    """Run a subcommand's work under the command line's conventions: ``(work(), None)``, or
    ``(None, status)`` after saying what stopped it in one line on stderr.

    Ctrl-C → :func:`interrupted` (130); an exception of a ``refused`` type → :func:`refuse`
    (2: a value found wrong once the work had begun, such as an output folder taken meanwhile);
    an exception ``failed`` gives a line for (a failure the command foresees, such as a full
    disk) → that line after ``prog: error:`` (1); any other exception →
    :func:`unexpected_error` (1, no traceback), its notes (``add_note``) in parentheses.
    ``note`` (or a function giving it, read when the work stops) says what was kept, e.g.
    "; nothing written"; it follows the interrupted and unexpected-error lines."""
    def said() -> str:
        return note() if callable(note) else note
    try:
        return work(), None
    except KeyboardInterrupt:
        return None, interrupted(prog, said())
    except refused as err:
        return None, refuse(prog, err, command, fold=fold)
    except Exception as err:  # one line, no traceback
        line = failed(err) if failed is not None else None
        if line is not None:
            print(f"{prog}: error: {line}", file=sys.stderr)
            return None, 1
        notes = " ".join(getattr(err, "__notes__", []))
        return None, unexpected_error(prog, err, said() + (f" ({notes})" if notes else ""))


class OneLineParser(argparse.ArgumentParser):
    """ArgumentParser whose errors are a single line (no usage block)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def command_line(argv: list[str]) -> str:
    """The command as run, for a result's provenance."""
    return " ".join([PROG, *argv])


__all__ = ["PROG", "message", "refuse", "interrupted", "INTERRUPT_GRACE_S",
           "exit_promptly_on_interrupt", "exit_now", "unexpected_error", "guarded",
           "OneLineParser", "command_line"]
