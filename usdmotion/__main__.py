"""``python -m usdmotion`` and the ``usdmotion`` console script.

:func:`run` routes Ctrl-C to one line and exit code 130 before anything else is imported:
the CLI's imports (typer, the command's module) take a tenth of a second or more, and an
interrupt there would otherwise print a Python traceback. Once :func:`usdmotion.cli.main`
runs, its own handlers take over (they also remove temporary files of atomic writes).

It also collects garbage less often: the imports (typer, NumPy, pxr) make about 10^5
objects and almost no garbage, and the default threshold (a collection every 700 new
objects) spent 0.01 s of every command's CPU time walking them (``benchmarks/startup.py``);
every 50,000 new objects keeps cyclic garbage collected in long runs (the Studio's server).

And it lets NumPy's OpenBLAS worker threads sleep as soon as they are idle
(``OPENBLAS_THREAD_TIMEOUT=4``, unless set): by default each spins, polling for work, for
about 2^28 cycles after the library loads, although no command's BLAS calls come that early:
0.015–0.02 s of CPU time of every command that imports NumPy, taken from the main thread on a
busy machine (``benchmarks/startup.py``). BLAS calls still use every core.
"""

import gc
import os
import signal


def _interrupted_while_starting(signum: int, frame) -> None:
    os.write(2, b"usdmotion: error: interrupted; no partial output was kept\n")  # nothing written yet
    os._exit(128 + signum)


def prepare_process() -> None:
    """The process settings of the module docstring (``benchmarks/startup.py`` applies them too)."""
    gc.set_threshold(50_000, 20, 10)
    os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")  # read when NumPy loads OpenBLAS


def run() -> None:
    """Console-script entry point."""
    signal.signal(signal.SIGINT, _interrupted_while_starting)
    prepare_process()
    from usdmotion.cli import run as run_cli

    run_cli()


if __name__ == "__main__":
    run()
