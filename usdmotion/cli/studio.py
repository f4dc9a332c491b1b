"""``usdmotion studio [PATH ...]``: a local web app to browse, play and compare takes."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated

import typer

from usdmotion.cli._options import ReadOptions, reads_motion
from usdmotion.cli.app import app


@app.command()
@reads_motion
def studio(
    paths: Annotated[list[Path] | None, typer.Argument(help="Library folders (searched with their subfolders) "
                                                            "or motion files. Default: the current folder.",
                                                       show_default=False)] = None,
    host: Annotated[str, typer.Option(help="Address to listen on (127.0.0.1: this machine only).")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="Port to listen on (0: any free port).")] = 8765,
    open_browser: Annotated[bool, typer.Option("--open/--no-open", help="Open the app in the web browser.")] = True,
    out: Annotated[Path, typer.Option(help="The only folder the studio may write to.")] = Path("out/studio"),
    allow_host: Annotated[list[str] | None, typer.Option(
        help="Another name the studio is opened by (besides localhost, 127.0.0.1 and --host), e.g. a "
             "reverse proxy's; repeatable. Requests naming any other host are refused.", show_default=False)] = None,
    read: ReadOptions = ReadOptions(),
) -> None:
    """Browse, play and compare takes in the web browser (Ctrl+C stops the server)."""
    from usdmotion.studio.server import serve

    def ready(url: str) -> None:
        typer.echo(f"usdmotion studio: {url} (writes only under {out}; Ctrl+C to stop)", err=True)

    serve(paths or [Path(".")], host, port, out, dataclasses.asdict(read), open_browser, ready, allow_host or ())
