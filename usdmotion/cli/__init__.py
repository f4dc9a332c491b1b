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

import importlib
import os
import pkgutil
import sys
import warnings

from usdmotion.cli.app import app
from usdmotion.errors import UsdMotionError

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


def _error(message: str) -> None:
    print(f"usdmotion: error: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 checks failed / internal error, 2 bad input)."""
    import typer

    _load_commands(sys.argv[1:] if argv is None else argv)
    debug = bool(os.environ.get("USDMOTION_DEBUG"))
    previous = warnings.showwarning
    warnings.showwarning = _show_warning
    try:
        result = app(args=argv, prog_name="usdmotion", standalone_mode=False)
        return int(result) if isinstance(result, int) else 0
    except typer.Exit as exc:
        return int(exc.exit_code)
    except typer.Abort:
        _error("aborted")
        return 130
    except typer.TyperException as exc:  # usage errors: bad option, missing argument
        message = exc.format_message().splitlines()
        _error((message[0] if message else type(exc).__name__) + " (see --help)")
        return 2
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    except UsdMotionError as exc:
        if debug:
            raise
        _error(str(exc).splitlines()[0])
        return 2
    except (ValueError, KeyError, OSError, MemoryError) as exc:
        if debug:
            raise
        text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        _error(f"{str(text).splitlines()[0] if str(text) else type(exc).__name__}")
        return 2
    except Exception as exc:  # a bug: still one line, non-zero
        if debug:
            raise
        _error(f"internal error ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}); "
               "rerun with USDMOTION_DEBUG=1 for a traceback")
        return 1
    finally:
        warnings.showwarning = previous


def run() -> None:
    """Console-script entry point."""
    sys.exit(main())
