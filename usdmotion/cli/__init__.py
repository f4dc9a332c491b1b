"""Command line: ``usdmotion <command>``.

Each public module of this package defines one command on :data:`app`; they are
imported here (sorted by name), so adding a command means adding a module. ``main``
turns every input error into one line on stderr and exit code 2 (no traceback); set
``USDMOTION_DEBUG=1`` to see tracebacks.
"""

from __future__ import annotations

import importlib
import os
import pkgutil
import sys
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


def _load_commands() -> None:
    names = [m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_") and m.name != "app"]
    names.sort(key=lambda n: (_COMMAND_ORDER.index(n) if n in _COMMAND_ORDER else len(_COMMAND_ORDER), n))
    for name in names:
        importlib.import_module(f"{__name__}.{name}")
    for info in app.registered_commands:
        module = info.callback.__module__.rsplit(".", 1)[-1] if info.callback else ""
        if not isinstance(info.rich_help_panel, str):  # typer's unset default is a placeholder
            info.rich_help_panel = _PANELS.get(module, "Edit")


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    text = str(message).splitlines()[0] if str(message) else category.__name__
    print(f"usdmotion: warning: {text}", file=sys.stderr)


def _error(message: str) -> None:
    print(f"usdmotion: error: {message}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 1 checks failed / internal error, 2 bad input)."""
    import typer

    from usdmotion.errors import UsdMotionError

    _load_commands()
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
