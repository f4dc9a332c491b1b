"""The typer application every command module registers on."""

from __future__ import annotations

import typer

app = typer.Typer(
    name="usdmotion",
    help="Motion capture → OpenUSD assets, retargeting, analysis, editing and feedback videos.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _print_version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        typer.echo(f"usdmotion {version('usdmotion')}")
        raise typer.Exit()


@app.callback()
def _options(version: bool = typer.Option(False, "--version", help="Print the version and exit.", is_eager=True,
                                          callback=_print_version)) -> None:
    """Motion capture → OpenUSD assets, retargeting, analysis, editing and feedback videos."""
