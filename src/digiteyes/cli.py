"""The ``digiteyes`` command. Each sub-command lives in :mod:`digiteyes.commands`.

Errors of digiteyes (bad files, bad states, bad cameras) print as one line and exit 2;
Ctrl-C exits 130 after the command has flushed what it had.
"""

from __future__ import annotations

import sys

import click

from digiteyes import __version__
from digiteyes.commands.bench import bench
from digiteyes.commands.demo import demo
from digiteyes.commands.evaluate import evaluate
from digiteyes.commands.model import model
from digiteyes.commands.mouse import mouse
from digiteyes.commands.render import render
from digiteyes.commands.track import track
from digiteyes.commands.track_many import track_many_command
from digiteyes.errors import DigitEyesError


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="digiteyes")
def cli() -> None:
    """Model-based 3D tracking of articulated objects (the hand first) from video."""


for command in (demo, model, render, track, evaluate, bench, mouse, track_many_command):
    cli.add_command(command)


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turning digiteyes errors into one clear line."""
    try:
        cli.main(args=argv, prog_name="digiteyes", standalone_mode=False)
    except DigitEyesError as exc:
        click.echo(f"digiteyes: error: {exc}", err=True)
        return 2
    except click.exceptions.Abort:
        click.echo("digiteyes: interrupted", err=True)
        return 130
    except KeyboardInterrupt:
        click.echo("digiteyes: interrupted", err=True)
        return 130
    except click.ClickException as exc:
        exc.show()
        return exc.exit_code
    except OSError as exc:
        click.echo(f"digiteyes: error: {exc}", err=True)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
