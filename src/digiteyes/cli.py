"""The ``digiteyes`` command. Each sub-command lives in :mod:`digiteyes.commands`.

Errors of digiteyes (bad files, bad states, bad cameras) and of the command line print as
one line ``digiteyes: error: ...`` and exit 2; Ctrl-C and SIGTERM exit 130 after the
command has flushed what it had, even during the first seconds spent importing.
"""

from __future__ import annotations

import os
import signal
import sys
import threading


def _interrupted_while_loading(signum: int, frame: object) -> None:
    """Ctrl-C while the libraries load: one line, exit 130 at once. Raising
    KeyboardInterrupt here is not enough: an import can surface it wrapped (a dataclass
    field's ``__set_name__`` turns it into a RuntimeError), as a traceback. Nothing has
    been written yet, so nothing is lost by not unwinding."""
    os.write(2, b"digiteyes: interrupted\n")
    os._exit(130)


_guarded = threading.current_thread() is threading.main_thread()
_previous_sigint = signal.signal(signal.SIGINT, _interrupted_while_loading) if _guarded else None
try:
    import click

    from digiteyes import __version__
    from digiteyes._signals import sigterm_as_interrupt
    from digiteyes.commands.bench import bench
    from digiteyes.commands.calibrate_camera import calibrate_camera
    from digiteyes.commands.calibrate_hand import calibrate_hand
    from digiteyes.commands.demo import demo
    from digiteyes.commands.evaluate import evaluate
    from digiteyes.commands.export import export
    from digiteyes.commands.model import model
    from digiteyes.commands.mouse import mouse
    from digiteyes.commands.pose import pose
    from digiteyes.commands.prior import prior
    from digiteyes.commands.render import render
    from digiteyes.commands.track import track
    from digiteyes.commands.track_many import track_many_command
    from digiteyes.errors import DigitEyesError
finally:
    if _guarded:
        signal.signal(signal.SIGINT, _previous_sigint)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="digiteyes")
def cli() -> None:
    """Model-based 3D tracking of articulated objects (the hand first) from video."""


for command in (demo, model, render, track, evaluate, export, bench, prior, pose,
                calibrate_camera, calibrate_hand, mouse, track_many_command):
    cli.add_command(command)


def _error(message: str) -> int:
    click.echo(f"digiteyes: error: {message}", err=True)
    return 2


def main(argv: list[str] | None = None) -> int:
    """Entry point: run the CLI, turning digiteyes errors into one clear line."""
    try:
        with sigterm_as_interrupt():
            code = cli.main(args=argv, prog_name="digiteyes", standalone_mode=False)
    except DigitEyesError as exc:
        return _error(str(exc))
    except (click.exceptions.Abort, KeyboardInterrupt):
        click.echo("digiteyes: interrupted", err=True)
        return 130
    except RuntimeError as exc:  # Ctrl-C inside a class being made by a late import
        if not isinstance(exc.__cause__, KeyboardInterrupt):
            raise
        click.echo("digiteyes: interrupted", err=True)
        return 130
    except click.ClickException as exc:
        context = getattr(exc, "ctx", None)
        hint = f" (see '{context.command_path} --help')" if context is not None else ""
        return _error(f"{exc.format_message()}{hint}")
    except OSError as exc:
        return _error(str(exc))
    except MemoryError:
        return _error("out of memory: the inputs ask for more than this computer has")
    return code if isinstance(code, int) else 0


if __name__ == "__main__":
    sys.exit(main())
