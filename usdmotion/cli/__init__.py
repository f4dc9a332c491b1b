"""Command line: ``usdmotion <command>``.

Each public module of this package defines one command on :data:`app`; they are
imported here (sorted by name), so adding a command means adding a module. ``main``
turns every input error into one line on stderr and exit code 2 (no traceback); set
``USDMOTION_DEBUG=1`` to see tracebacks.

Only the invoked command's module is imported (all of them for ``--help``). Command modules
import the library (``usdmotion.io``, ``ops``, ``render``: NumPy, pyarrow, pxr, JAX, ...)
inside the command function, deliberately: ``usdmotion --help`` imports every command module
and must stay fast (``tests/test_startup.py``); light modules (errors, options, progress)
are imported at the top.
"""

from __future__ import annotations

import atexit
import importlib
import os
import pkgutil
import signal
import sys
import threading
import warnings

from usdmotion.cli.app import app

_COMMAND_ORDER = ("convert", "info", "positions")
#: Help panels by command module (``usdmotion --help`` groups commands by what they are for).
_PANELS = {
    "convert": "Convert and inspect", "info": "Convert and inspect", "positions": "Convert and inspect",
    "retarget": "Retarget", "render": "Render",
    "analyze": "Biomechanics", "check": "Biomechanics", "synth": "Biomechanics",
    "segment": "Segment", "segment_eval": "Segment", "studio": "Studio",
}


def _command_modules() -> list[str]:
    """The command modules' names, in help order."""
    names = [m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_") and m.name != "app"]
    return sorted(names, key=lambda n: (_COMMAND_ORDER.index(n) if n in _COMMAND_ORDER else len(_COMMAND_ORDER), n))


def _load_commands(argv: list[str] | None = None) -> None:
    """Import the command modules: only the invoked one where ``argv`` names one (start-up is
    the user's time: ``usdmotion info`` need not import the renderer's or retargeter's CLI),
    none for ``--version`` alone, else all of them (``argv`` None, ``--help``, an unknown command)."""
    names = _command_modules()
    invoked = next((a for a in argv or () if not a.startswith("-")), None)
    module = invoked.replace("-", "_") if invoked else None
    version_only = invoked is None and argv is not None and "--version" in argv
    for name in [] if version_only else [module] if module in names else names:
        importlib.import_module(f"{__name__}.{name}")
    order = {f"{__name__}.{name}": i for i, name in enumerate(names)}
    app.registered_commands.sort(key=lambda info: order.get(getattr(info.callback, "__module__", ""), len(order)))
    for info in app.registered_commands:
        module_name = info.callback.__module__.rsplit(".", 1)[-1] if info.callback else ""
        if not isinstance(info.rich_help_panel, str):  # typer's unset default is a placeholder
            info.rich_help_panel = _PANELS.get(module_name, "Edit")


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    text = str(message).splitlines()[0] if str(message) else category.__name__
    print(f"usdmotion: warning: {text}", file=sys.stderr)


class Terminated(KeyboardInterrupt):
    """SIGTERM/SIGHUP received: unwinds like Ctrl-C, so every ``finally`` (temporary
    files of atomic writes, render writers) runs before the process exits."""


#: Signals received during :func:`main` (typer turns a KeyboardInterrupt into a plain
#: exit code 130, so the handler records what happened).
_received: list[int] = []


def _on_signal(signum, frame) -> None:
    _received.append(signum)
    if len(_received) > 1:  # already unwinding: let the cleanup finish
        return
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated(signal.Signals(signum).name)


def _install_signal_handlers() -> dict:
    """Route SIGINT, SIGTERM and SIGHUP through :func:`_on_signal`; returns the previous handlers."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    return {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}


def _interrupted() -> int:
    """One line and the shell's exit code for the first signal received: 128 + its number."""
    signum = _received[0] if _received else signal.SIGINT
    if signum == signal.SIGINT:
        _error("interrupted; no partial output was kept")
    else:
        _error(f"terminated by {signal.Signals(signum).name}; no partial output was kept")
    return 128 + int(signum)


def _error(message: str) -> None:
    print(f"usdmotion: error: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 checks failed / internal error, 2 bad input)."""
    import typer

    from usdmotion.errors import INPUT_ERRORS, error_message

    debug = bool(os.environ.get("USDMOTION_DEBUG"))
    previous = warnings.showwarning
    warnings.showwarning = _show_warning
    _received.clear()
    handlers = _install_signal_handlers()
    try:
        _load_commands(sys.argv[1:] if argv is None else argv)
        result = app(args=argv, prog_name="usdmotion", standalone_mode=False)
        if _received:  # typer returned 130 for an interrupt
            return _interrupted()
        return int(result) if isinstance(result, int) else 0
    except typer.Exit as exc:
        return _interrupted() if _received else int(exc.exit_code)
    except typer.Abort:
        _error("aborted")
        return 130
    except typer.TyperException as exc:  # usage errors: bad option, missing argument
        if type(exc).__name__ == "NoArgsIsHelpError":  # `usdmotion`, `usdmotion batch`: the help is printed
            return 0
        message = exc.format_message().splitlines()
        _error((message[0] if message else type(exc).__name__) + " (see --help)")
        return 2
    except KeyboardInterrupt:
        return _interrupted()
    except INPUT_ERRORS as exc:
        if debug:
            raise
        _error(error_message(exc))
        return 2
    except Exception as exc:  # a bug: still one line, non-zero
        if debug:
            raise
        _error(f"{error_message(exc)}; rerun with USDMOTION_DEBUG=1 for a traceback")
        return 1
    finally:
        warnings.showwarning = previous
        for sig, handler in handlers.items():
            signal.signal(sig, handler)


def run() -> None:
    """Console-script entry point.

    After a signal, every ``finally`` has run (no temporary file is left); the process
    then ends at once, skipping the teardown of C++ libraries whose worker threads the
    interrupt left mid-task (Arrow's would abort with ``terminate called ...``).

    A command that succeeded and left nothing to run at exit (no ``atexit`` callback, e.g.
    a ``weakref.finalize`` of a temporary folder, no other Python thread) ends the same way
    once stdout and stderr are flushed: its files were written and closed, atomically, by
    then, and the interpreter's teardown (every module's objects, pxr's and NumPy's
    libraries) is 0.008–0.010 s of every ``info``/``convert`` (``benchmarks/startup.py``).
    """
    code = main()
    if _received:
        _flushed()
        os._exit(code)
    if code == 0 and not atexit._ncallbacks() and threading.active_count() == 1 and _flushed():
        os._exit(0)
    # No gc.freeze() here: frozen objects escape the interpreter's last collection, and
    # OpenImageIO's nanobind bindings then print hundreds of "leaked instance" lines on a
    # successful command (a PNG still or sequence).
    sys.exit(code)


def _flushed() -> bool:
    """Flush stdout and stderr; False if one could not be (e.g. a closed pipe: the
    interpreter's own exit then reports it as usual)."""
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        return False
    return True
