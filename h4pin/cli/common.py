# SPDX-License-Identifier: Apache-2.0
"""What every command of ``h4pin`` shares: the Typer app, the option texts, one-line failures
(:func:`fail`), the signal handling of long commands, and the robot loaders of ``--variant``,
``--urdf`` and ``--robot``."""


from __future__ import annotations

import functools
import math
import signal
from pathlib import Path
from typing import Any, Literal

import typer
import typer.main

from h4pin.description.params import VARIANTS
from h4pin.stiffness.eq30 import MODELS

#: ``--variant`` and ``--model`` as choices (typer takes a ``Literal`` as a click choice).
Variant = Literal[VARIANTS]  # type: ignore[valid-type]
Model = Literal[MODELS]  # type: ignore[valid-type]

app = typer.Typer(add_completion=False, pretty_exceptions_enable=False, rich_markup_mode=None,
                  help="The H4 parallel robot on Pinocchio and its stiffness (Company et al., ICRA 2005), and any "
                  "closed-loop robot's (--robot FILE). Guides, API reference and examples: the docs/ folder of the "
                  "source (and of the sdist), a site that `python -m sphinx -W -b html docs docs/_build/html` builds "
                  "(the docs extra) into docs/_build/html/index.html.")


def _version(value: bool) -> None:
    if value:
        from h4pin._version import __version__

        typer.echo(f"h4pin {__version__}")
        raise typer.Exit(0)


@app.callback(invoke_without_command=True)
def _root(ctx: typer.Context, version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                                           help="print h4pin's version and exit")) -> None:
    """The H4 parallel robot on Pinocchio and its stiffness (Company et al., ICRA 2005), and any
    closed-loop robot's (--robot FILE)."""
    if ctx.invoked_subcommand is None:  # a bare `h4pin`: the help, and success
        typer.echo(ctx.get_help())
        raise typer.Exit(0)


class Stopped(BaseException):
    """SIGTERM or SIGHUP arrived: unwinds like Ctrl-C's KeyboardInterrupt, so cleanups run."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def stop_on_signal(signum: int, _frame: object) -> None:
    raise Stopped(signum)


STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)

# Options that take a fixed number of values: a wrong count is reported against the option.
ARITY = {"--pose": (4, "X Y Z THETA (m, rad)"), "--load": (3, "FX FY FZ (N)")}


def is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def check_arity(argv: list[str]) -> None:
    """Refuse ``--pose``/``--load`` followed by another count of numbers than they take (click
    would report a missing value vaguely, or an extra one as an unexpected argument)."""
    for n, token in enumerate(argv):
        name = token.split("=", 1)[0]
        if name not in ARITY or "=" in token:
            continue
        count, what = ARITY[name]
        values = 0
        while n + 1 + values < len(argv) and is_number(argv[n + 1 + values]):
            values += 1
        if values != count:
            got = " ".join(argv[n + 1:n + 1 + values]) or "nothing"
            fail(f"{name} takes {count} numbers {what}, got {values}: {got}")


def check_finite(name: str, values: tuple[float, ...] | None) -> None:
    """Refuse NaN or infinite values of an option."""
    if values is not None and not all(math.isfinite(v) for v in values):
        fail(f"{name} must be finite numbers, got {' '.join(f'{v:g}' for v in values)}")


def fail(message: str) -> None:
    """Print a one-line error and exit with status 2."""
    typer.echo(f"error: {message}", err=True)
    raise typer.Exit(2)


def wrote(*paths: Path | str) -> None:
    """One line ``wrote PATH`` per file a command wrote, in order."""
    for path in paths:
        typer.echo(f"wrote {path}")


def load_robot(variant: str | None, urdf: Path | None):
    """The robot named by ``--variant`` or ``--urdf`` (not both)."""
    from h4pin.robot import load

    if variant and urdf:
        fail("give --variant or --urdf, not both")
    return load(urdf if urdf else (variant or "prototype"))  # springs within h4pin.limits.SPRING_RANGES


# What the options every command shares say (typer.Option is called in each signature).
VARIANT = "shipped variant (default: prototype)"
URDF = "path to an H4 URDF instead of a variant"
MODEL = ("'paper' (eq. 30 as printed, the default of h4pin.compliance) or 'consistent' (erratum 4 fixed: "
         "symmetric K)")
QUIET = "no progress bar"
OVERWRITE = "replace an existing output that h4pin did not write (without it only h4pin's own files are replaced)"
PAYLOAD = "point payload at D, kg (0: none)"
# What the options of any closed-loop robot say (atlas, view).
ROBOT = "a closed-loop robot's URDF (with its Gepetto sidecar YAML) or MJCF file (.xml)"
SIDECAR = "with --robot FILE.urdf: its closed-loop sidecar (default: FILE.yaml)"
MOTOR_K = ("stiffness of each motor, N.m/rad (N/m), when the file has no joint springs (docs/mechanisms.md: "
           "the file's springs where it has them)")
JOINT_K = "stiffness of every other joint, N.m/rad (N/m); 0 leaves the passive joints free"

#: The one exception to ``--model paper``: the cycle's dynamic part (h4pin.studies.cycle.dynamic_deflection)
#: divides by the first natural frequency of the symmetric part of K^-1, which the paper's
#: unsymmetric K leaves indefinite (ZeroDivisionError), so ``h4pin cycle`` keeps its model until
#: the study takes the paper model.
CYCLE_MODEL = "consistent"


def check_payload(values: float | list[float]) -> None:
    """Refuse a ``--payload`` that is not a finite mass >= 0."""
    for p in values if isinstance(values, list) else [values]:
        if not (math.isfinite(p) and p >= 0):
            fail(f"--payload must be a finite mass >= 0 in kg, got {p:g}")





def restoring_signals(command: Any) -> Any:
    """The command with the process's SIGINT, SIGTERM and SIGHUP handlers restored when it
    returns: run in-process (a test, a notebook), it leaves its caller's handlers as they were."""

    @functools.wraps(command)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, *STOP_SIGNALS)}
        try:
            return command(*args, **kwargs)
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)

    return wrapper



def given(ctx: typer.Context, name: str) -> bool:
    """Whether the option ``name`` of the command of ``ctx`` was given (not its default)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name != "DEFAULT"


def load_mechanism(robot: Path, sidecar: Path | None):
    """The :class:`h4pin.mechanism.Mechanism` of ``--robot`` (a URDF and its sidecar, or an MJCF)."""
    from h4pin.files import check_input
    from h4pin.mechanism import Mechanism

    check_input(robot, "--robot")  # a FIFO, a device or a folder refused by name
    if robot.suffix.lower() == ".xml":
        if sidecar is not None:
            fail("--sidecar goes with a URDF (an MJCF file holds its closures)")
        return Mechanism.from_mjcf(robot)
    return Mechanism.from_urdf(robot, sidecar)


