# SPDX-License-Identifier: Apache-2.0
"""Command line: ``h4pin table2`` (the paper's Table II), ``h4pin view`` (meshcat viewer),
``h4pin export --out PATH`` (MuJoCo model), the studies; ``docs/cli.md`` lists every command and
option (:func:`reference` writes it).

One convention: ``--model`` is ``paper`` unless told (as :func:`h4pin.compliance`; ``cycle``:
:data:`CYCLE_MODEL`); enumerations
(``--model``, ``--variant``) are choices; ``--out PATH`` is a command's main output (a file, or a
store for a sweep), ``--figure PATH`` its picture (PNG) and ``--figures DIR`` a folder of them;
``--quiet`` hides progress bars; ``--payload KG`` is a point mass at D in kg (>= 0). Options
renamed to fit (``--html``, ``--mjcf``, ``--map``, ``--pareto``) are still taken for one release,
hidden, with a one-line warning on stderr (:data:`RENAMED`).

Outputs: an existing file is replaced only if h4pin wrote it (:func:`h4pin.files.written_by_h4pin`)
or with ``--overwrite``; otherwise the command exits 2 before any work and the file is untouched.

Errors a user can act on (unreachable or singular pose, bad parameter, malformed URDF, bad
arguments) print one line on stderr and exit with status 2; nothing is half-written.

``h4pin view`` without ``--out`` serves the scene until it is stopped. Whatever stops it, its
meshcat server stops too, and the exit status says why, as shells do for a signal (128 + its
number): Ctrl-C (SIGINT) exits 130, SIGTERM 143, SIGHUP (terminal closed) 129. A signal the
command was started with ignored (``nohup``, a shell's background job) stays ignored.
"""

from __future__ import annotations

import functools
import inspect
import math
import signal
import sys
from pathlib import Path
from typing import Any, Literal

import typer
import typer.main

from h4pin.description.params import VARIANTS
from h4pin.errors import H4Error
from h4pin.stiffness.eq30 import MODELS

#: ``--variant`` and ``--model`` as choices (typer takes a ``Literal`` as a click choice).
Variant = Literal[VARIANTS]  # type: ignore[valid-type]
Model = Literal[MODELS]  # type: ignore[valid-type]

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False, rich_markup_mode=None,
                  help="The H4 parallel robot on Pinocchio and its stiffness (Company et al., ICRA 2005).")


@app.callback()
def _root() -> None:
    """The H4 parallel robot on Pinocchio and its stiffness (Company et al., ICRA 2005)."""
    _warnings.clear()


class Stopped(BaseException):
    """SIGTERM or SIGHUP arrived: unwinds like Ctrl-C's KeyboardInterrupt, so cleanups run."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


def _stop_on_signal(signum: int, _frame: object) -> None:
    raise Stopped(signum)


STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)

# Options that take a fixed number of values: a wrong count is reported against the option.
ARITY = {"--pose": (4, "X Y Z THETA (m, rad)"), "--load": (3, "FX FY FZ (N)")}


def _is_number(token: str) -> bool:
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
        while n + 1 + values < len(argv) and _is_number(argv[n + 1 + values]):
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


#: Options renamed to the convention: old name -> new name. The old names are hidden options that
#: still work for one release, with a one-line warning.
RENAMED = {"--html": "--out", "--mjcf": "--out", "--map": "--figure", "--pareto": "--figure"}


_warnings: list[str] = []


def renamed(new: Any, old: Any, old_name: str) -> tuple[Any, str]:
    """The value of an option given under its new name or its old one (:data:`RENAMED`), and the
    name the user typed (for messages). The old name's warning waits for :func:`warn_renamed`, so
    that an error stays one line."""
    new_name = RENAMED[old_name]
    if old is None:
        return new, new_name
    if new is not None:
        fail(f"give {new_name}, not both {new_name} and {old_name} (its old name)")
    _warnings.append(f"h4pin: {old_name} is deprecated, use {new_name} ({old_name} goes in the next release)")
    return old, old_name


def warn_renamed() -> None:
    """Print the warnings of old option names (once the arguments passed their checks)."""
    while _warnings:
        typer.echo(_warnings.pop(0), err=True)


@app.command()
def table2(
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    model: Model = typer.Option("paper", help=MODEL),
    match: bool = typer.Option(False, "--measured-match", help="side by side: this robot, the 'measured_match' "
                               "variant (a saturated fit of the measured table) at its point, the paper's tables"),
) -> None:
    """Table II of the paper: compliance at q_i = 45 deg beside the paper's computed and measured tables."""
    from h4pin.studies.table2 import report, report_match

    typer.echo((report_match if match else report)(load_robot(variant, urdf), model=model))


def _restoring_signals(command: Any) -> Any:
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


@app.command()
@_restoring_signals
def view(
    ctx: typer.Context,
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    pose: tuple[float, float, float, float] | None = typer.Option(
        None, metavar="X Y Z THETA", help="pose of D in m and rad (default: all actuators at 45 deg)"),
    load: tuple[float, float, float] | None = typer.Option(
        None, metavar="FX FY FZ", help="force at D in N: draws the deflected robot and the load"),
    field: bool = typer.Option(False, "--field", help="also draw an ellipsoid field over the workspace"),
    rotational: bool = typer.Option(False, "--rotational", help="also draw the rotational ellipsoid"),
    out: Path | None = typer.Option(None, metavar="PATH",
                                    help="write a self-contained HTML page here and exit (no server)"),
    scale: float | None = typer.Option(None, help="ellipsoid scale, mm per um/N (default: automatic)"),
    exaggeration: float | None = typer.Option(None, help="factor on the drawn deflection (default: automatic)"),
    model: Model = typer.Option("paper", help=MODEL),
    host: str = typer.Option("127.0.0.1", help="interface the server listens on; 0.0.0.0 lets other machines in"),
    mode: int | None = typer.Option(None, help="also animate this natural mode of the elastic robot (1: the first)"),
    payload: float = typer.Option(0.0, metavar="KG", help=f"with --mode: {PAYLOAD}"),
    quiet: bool = typer.Option(False, "--quiet", help=f"{QUIET} (of --field)"),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
    html: Path | None = typer.Option(None, "--html", hidden=True, help="old name of --out"),
    robot: Path | None = typer.Option(None, metavar="FILE", help=f"{ROBOT}, drawn as sticks at its reference assembly "
                                      "instead of the H4 (--variant ... --payload do not apply)"),
    sidecar: Path | None = typer.Option(None, metavar="YAML", help=SIDECAR),
    output: str | None = typer.Option(None, metavar="FRAME", help="with --robot: the frame of the ellipsoid and the "
                                      "load (default: the atlas's)"),
    atlas_path: Path | None = typer.Option(None, "--atlas", metavar="PATH", help="with --robot: draw the ellipsoid "
                                           "field of this motor-space atlas (h4pin atlas --robot; its springs, "
                                           "locked joints and output by default)"),
    motor_stiffness: float = typer.Option(100.0, metavar="K", help=f"with --robot: {MOTOR_K}"),
    joint_stiffness: float = typer.Option(100.0, metavar="K", help=f"with --robot: {JOINT_K}"),
    lock: list[str] | None = typer.Option(None, metavar="JOINT", help="with --robot: a joint held rigid; repeat"),
) -> None:
    """Show the robot, its compliance ellipsoid and its deflection in meshcat (browser). With
    --robot FILE, any closed-loop robot: its sticks, ellipsoid, atlas field and deflected shape.

    Ctrl-C, SIGTERM and SIGHUP stop the server (exit 130, 143, 129)."""
    import time

    out, out_name = renamed(out, html, "--html")
    for sig in STOP_SIGNALS:
        if signal.getsignal(sig) is not signal.SIG_IGN:  # nohup's choice stands
            signal.signal(sig, _stop_on_signal)
    from h4pin import limits

    check_finite("--pose", pose)
    check_finite("--load", load)
    if load is not None:
        limits.check_range("--load", load, "load")
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        fail(f"--scale must be a finite number > 0 (mm per um/N), got {scale:g}")
    if scale is not None:
        limits.check_range("--scale", scale, "scale")
    if exaggeration is not None and not (math.isfinite(exaggeration) and exaggeration > 0):
        fail(f"--exaggeration must be a finite number > 0, got {exaggeration:g}")
    if exaggeration is not None:
        limits.check_range("--exaggeration", exaggeration, "exaggeration")
    if mode is not None and mode < 1:
        fail(f"--mode must be >= 1 (1: the first natural mode), got {mode}")
    check_payload(payload)
    limits.check_range("--payload", payload, "payload")
    if payload > 0 and mode is None:
        fail("--payload goes with --mode (the payload of the animated mode)")
    from h4pin.files import check_output, check_replace
    from h4pin.io import meshcat_server, viewer

    if out is not None:
        if out.is_dir():
            fail(f"{out_name} {out} is a folder: give the path of the page to write, e.g. {out / 'h4.html'}")
        check_output(out, out_name)
        check_replace(out, out_name, overwrite)
    else:
        meshcat_server.check_host(host)

    import numpy as np

    from h4pin.elastic import Payload
    from h4pin.kinematics.closed_form import centre_pose

    warn_renamed()
    mech_options = ("sidecar", "output", "atlas_path", "motor_stiffness", "joint_stiffness", "lock")
    if robot is not None:
        h4_only = [n for n in ("variant", "urdf", "pose", "field", "rotational", "model", "mode", "payload")
                   if _given(ctx, n)]
        if h4_only:
            fail(f"--{h4_only[0]} is an option of the H4's view, not of --robot")
        own = any(_given(ctx, n) for n in ("motor_stiffness", "joint_stiffness", "lock"))
        scene = _mechanism_scene(robot, sidecar, output, atlas_path, (motor_stiffness, joint_stiffness) if own
                                 else None, lock or [], load, scale, exaggeration, host)
    elif given := [n.replace("_path", "").replace("_", "-") for n in mech_options if _given(ctx, n)]:
        fail(f"--{given[0]} goes with --robot FILE")
    else:
        h4 = load_robot(variant, urdf)
        # The field and the mode are drawn here rather than by viewer.show (same order), for --quiet.
        scene = viewer.show(h4, None if pose is None else list(pose), None if load is None else list(load),
                            scale=scale, exaggeration=exaggeration, rotational=rotational, model=model, host=host)
    try:
        if field:
            scene.field(viewer.workspace_grid(h4), model, progress=not quiet)
        if mode is not None:
            x = centre_pose(h4) if pose is None else np.array(pose, dtype=float)
            scene.mode(x, mode - 1, Payload(payload) if payload > 0 else None)
        for line in scene.legend:
            typer.echo(line)
        if out is not None:
            wrote(scene.write_html(out))
            return
        typer.echo(f"meshcat: {scene.url}  (Ctrl-C to stop the server)")
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        typer.echo("stopped")
        raise typer.Exit(128 + signal.SIGINT) from None
    except Stopped as stop:
        typer.echo(f"stopped ({stop})")
        raise typer.Exit(128 + stop.signum) from None
    finally:
        for sig in (signal.SIGINT, *STOP_SIGNALS):  # a second signal must not interrupt the cleanup
            signal.signal(sig, signal.SIG_IGN)
        scene.close()


@app.command()
def tolerance(
    variant: Variant | None = typer.Option(None, help=f"nominal robot: {VARIANT}"),
    urdf: Path | None = typer.Option(None, help=f"nominal robot: {URDF}"),
    robots: int = typer.Option(1000, help="robots drawn"),
    seed: int = typer.Option(0, help="seed of the draws"),
    sigma: list[str] = typer.Option([], metavar="NAME=METRES",
                                    help="sigma of one tolerance in m (forearm, A0, b, P, C0, l, mismatch)"),
    sensitivity: bool = typer.Option(True, help="also run one tolerance at a time"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH", help="write the histograms to this PNG"),
    model: Model = typer.Option("paper", help=MODEL),
    quiet: bool = typer.Option(False, "--quiet", help=QUIET),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
) -> None:
    """Tolerance study: compliance and static pose error of robots with manufacturing errors."""
    from h4pin.errors import ParameterError
    from h4pin.files import check_output, check_replace
    from h4pin.studies import tolerance as tol

    sigmas: dict[str, float] = {}
    for item in sigma:
        name, sep, value = item.partition("=")
        if not sep:
            raise ParameterError(f"--sigma must be NAME=METRES, got {item!r}")
        sigmas[name.strip()] = value  # type: ignore[assignment]  # checked by tol.check_sigmas
    sigmas = tol.check_sigmas(sigmas)
    if figure is not None:
        check_output(figure, "--figure", suffixes=(".png",))
        check_replace(figure, "--figure", overwrite)
    if robots < 1:
        fail(f"--robots must be >= 1, got {robots}")
    h4 = load_robot(variant, urdf)
    res = tol.study(h4, n_robots=robots, sigmas=sigmas, seed=seed, model=model, progress=not quiet)
    sens = tol.sensitivity(h4, n_robots=min(robots, 1000), sigmas=sigmas, seed=seed, model=model) if sensitivity \
        else None
    typer.echo(tol.report(res, sens))
    if figure is not None:
        wrote(tol.write_figure(res, figure))


@app.command()
def export(
    out: Path | None = typer.Option(None, metavar="PATH", help="write the robot as MuJoCo MJCF here (closures as "
                                    "connect equalities); required"),
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    elastic: bool = typer.Option(False, "--elastic", help="the elastic robot: every compliance a spring joint, "
                                 "actuators locked at the centre pose (h4pin.elastic_model)"),
    servo: bool = typer.Option(False, "--servo", help="with --elastic: the actuators kept and driven by position "
                               "servos (ctrl: 4 angles in rad, then 4 rates in rad/s), a model that can follow a "
                               "motion"),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
    robot: Path | None = typer.Option(None, metavar="PATH", help="any closed-loop robot instead of the H4: its URDF "
                                      "(with its closed-loop sidecar) or MJCF (.xml), written with --elastic by "
                                      "Mechanism.to_mjcf at its assembled configuration"),
    sidecar: Path | None = typer.Option(None, metavar="PATH", help="with --robot URDF: its closed-loop YAML sidecar "
                                        "(default: the URDF's path with .yaml)"),
    spring: list[str] | None = typer.Option(None, metavar="JOINT=K", help="with --robot: a joint's spring, N.m/rad "
                                            "or N/m; repeat for several (default: the file's springs); motors "
                                            "without one are locked"),
    site: list[str] | None = typer.Option(None, metavar="FRAME", help="with --robot: a site at this frame; repeat "
                                          "for several"),
    timestep: float = typer.Option(5e-5, metavar="S", help="with --robot: MuJoCo time step, s (light links need "
                                   "less: docs/mechanisms.md)"),
    mjcf: Path | None = typer.Option(None, "--mjcf", hidden=True, help="old name of --out"),
) -> None:
    """Export the robot for another tool: --out PATH writes a MuJoCo model (8 closures, 4 motors;
    with --elastic, the compliances as spring joints and the actuators locked, or with --servo
    driven by position servos); --robot PATH --elastic: any closed-loop robot, its springs as
    joint stiffness."""
    from h4pin.files import check_output, check_replace
    from h4pin.io.mjcf import write_mjcf

    out, out_name = renamed(out, mjcf, "--mjcf")
    if out is None:
        fail("Missing option '--out'.")
    if servo and not elastic:
        fail("--servo needs --elastic (only the elastic robot has servos)")
    check_output(out, out_name)
    check_replace(out, out_name, overwrite)
    warn_renamed()
    if robot is not None:
        if variant is not None or urdf is not None or servo or not elastic:
            fail("--robot takes --elastic, and neither --variant, --urdf nor --servo")
        wrote(_export_mechanism(robot, sidecar, spring, site or [], timestep, out, overwrite))
        return
    for name, given in (("--sidecar", sidecar), ("--spring", spring), ("--site", site)):
        if given:
            fail(f"{name} needs --robot")
    h4 = load_robot(variant, urdf)
    try:
        wrote(write_mjcf(h4, out, elastic=elastic, servo=servo))
    except OSError as exc:
        fail(f"cannot write {out}: {exc.strerror or exc}")


def _export_mechanism(robot: Path, sidecar: Path | None, spring: list[str] | None, sites: list[str],
                      timestep: float, out: Path, overwrite: bool) -> Path:
    """``h4pin export --robot``: the mechanism of a URDF (and sidecar) or MJCF file, assembled
    from its reference configuration, written by ``Mechanism.to_mjcf``."""
    from h4pin.elastic import Mechanism

    springs: dict[str, float] = {}
    for item in spring or []:
        joint, _, value = item.partition("=")
        if not joint or not _is_number(value):
            fail(f"--spring takes JOINT=K (K in N.m/rad or N/m), got {item!r}")
        springs[joint] = float(value)
    if not robot.is_file():
        fail(f"--robot {robot}: no such file")
    mech = Mechanism.from_mjcf(robot) if robot.suffix.lower() == ".xml" else Mechanism.from_urdf(robot, sidecar)
    return mech.to_mjcf(out, springs or dict(mech.springs), mech.assemble(), sites=sites, timestep=timestep,
                        overwrite=overwrite)


def _atlas_ranges(ds: Any, ok: Any, frequency: bool, where: str, fmt: str) -> None:
    """The ranges of an atlas's worst compliance (and first frequency) over its valid points."""
    if int(ok.sum()):
        c = ds.compliance_max * 1e6
        typer.echo(f"worst-direction compliance{where}: {float(c.min()):{fmt}} to {float(c.max()):{fmt}} um/N")
        if frequency:
            f = ds.first_frequency
            typer.echo(f"first natural frequency {float(f.min()):{fmt}} to {float(f.max()):{fmt}} Hz")


@app.command()
def atlas(
    ctx: typer.Context,
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    x: tuple[float, float, int] = typer.Option((-0.3, 0.3, 61), metavar="LO HI N", help="x grid, m"),
    y: tuple[float, float, int] = typer.Option((-0.3, 0.3, 61), metavar="LO HI N", help="y grid, m"),
    z: list[float] | None = typer.Option(None, metavar="Z",
                                         help="z of a slice, m; repeat for several (default: centre z)"),
    z_range: tuple[float, float, int] | None = typer.Option(None, metavar="LO HI N", help="3-D box: z grid, m"),
    theta: list[float] | None = typer.Option(None, metavar="THETA",
                                             help="theta of a slice, rad; repeat for several (default 0)"),
    model: Model = typer.Option("paper", help=f"{MODEL}; both give the same K_tt"),
    out: Path = typer.Option(Path("atlas.nc"), metavar="PATH", help="output file: .nc (NetCDF) or .zarr"),
    figures: Path | None = typer.Option(None, metavar="DIR", help="folder for the maps atlas_<quantity>.png"),
    frequency: bool = typer.Option(False, "--frequency", help="also the first natural frequency (Hz)"),
    quiet: bool = typer.Option(False, "--quiet", help=QUIET),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
    robot: Path | None = typer.Option(None, metavar="FILE", help=f"{ROBOT}: its motor-space atlas instead of the H4's "
                                      "workspace (the H4 options --variant ... --model do not apply)"),
    sidecar: Path | None = typer.Option(None, metavar="YAML", help=SIDECAR),
    output: str | None = typer.Option(None, metavar="FRAME", help="with --robot: the frame whose compliance is mapped"),
    motor: list[str] | None = typer.Option(None, metavar="NAME=LO:HI:N", help="with --robot: a motor's grid (rad or m);"
                                           " repeat per motor (default: its file range where finite, else the "
                                           "reference assembly +- 0.25 rad or 0.025 m)"),
    count: int | None = typer.Option(None, metavar="N", help="with --robot: grid points per motor not given by "
                                     "--motor (default: 21 for one or two motors, 7 for three, 3 beyond)"),
    motor_stiffness: float = typer.Option(100.0, metavar="K", help=f"with --robot: {MOTOR_K}"),
    joint_stiffness: float = typer.Option(100.0, metavar="K", help=f"with --robot: {JOINT_K}"),
    lock: list[str] | None = typer.Option(None, metavar="JOINT", help="with --robot: a joint held rigid; repeat"),
    threads: int | None = typer.Option(None, help="with --robot: threads of each block's compliance (default: one "
                                       "per core)"),
) -> None:
    """Workspace atlas: worst compliance, z stiffness, isotropy, cond(J), cond(M1), reachability
    (and the first natural frequency). With --robot FILE, any closed-loop robot's atlas over its
    motors: worst compliance and ellipsoid at --output, validity (and the first natural frequency)."""
    import numpy as np

    from h4pin.files import check_output, check_replace
    from h4pin.kinematics.closed_form import centre_pose
    from h4pin.studies import atlas as atlas_module

    if robot is not None:
        h4_only = [f"--{n.replace('_', '-')}" for n in ("variant", "urdf", "x", "y", "z", "z_range", "theta", "model")
                   if _given(ctx, n)]
        if h4_only:
            fail(f"{h4_only[0]} is an option of the H4's atlas; with --robot the grid is --motor NAME=LO:HI:N")
        return _motor_atlas(robot, sidecar, output, motor or [], count, motor_stiffness, joint_stiffness, lock or [],
                            threads, out, figures, frequency, quiet, overwrite)
    given = [f"--{n.replace('_', '-')}" for n in ("sidecar", "output", "motor", "count", "motor_stiffness",
                                                   "joint_stiffness", "lock", "threads") if _given(ctx, n)]
    if given:
        fail(f"{given[0]} goes with --robot FILE (any closed-loop robot's atlas)")
    if z and z_range:
        fail("give --z or --z-range, not both")
    for name, axis in (("--x", x), ("--y", y), ("--z-range", z_range)):
        if axis is not None and axis[2] < 1:
            fail(f"{name} LO HI N needs N >= 1, got {axis[2]}")
    atlas_module.check_out(out, "--out", overwrite)  # a .zarr store: an h4pin atlas, or --overwrite
    check_replace(out, "--out", overwrite)  # a .nc file
    if figures is not None:
        check_output(figures / "atlas_status.png", "--figures")
        maps = (*atlas_module.QUANTITIES, *(atlas_module.FREQUENCY if frequency else ()), "status")
        for q in maps:
            check_replace(figures / f"atlas_{q}.png", "--figures", overwrite)
    n_z = z_range[2] if z_range else max(len(z or []), 1)
    # a .zarr atlas streams to disk: its memory grows with its blocks, not with its poses
    atlas_module.check_memory((max(len(theta or []), 1), n_z, y[2], x[2]), frequency=frequency,
                              streamed=out.suffix == ".zarr")
    h4 = load_robot(variant, urdf)
    grid = {name: np.linspace(lo, hi, n) for name, (lo, hi, n) in (("x", x), ("y", y))}
    zs = np.linspace(*z_range[:2], z_range[2]) if z_range else (z or [float(centre_pose(h4)[2])])
    ds = atlas_module.atlas(h4, grid["x"], grid["y"], zs, theta or [0.0], model, progress=not quiet, out=out,
                            frequency=frequency, overwrite=overwrite)
    ok = ds.status == 0  # lazy (dask) for a streamed .zarr atlas: reduced chunk by chunk
    typer.echo(f"{int(ok.sum())} of {ok.size} poses reachable and regular")
    _atlas_ranges(ds, ok, frequency, "", ".1f")
    wrote(out, *(atlas_module.plot(ds, figures) if figures is not None else ()))



def _given(ctx: typer.Context, name: str) -> bool:
    """Whether the option ``name`` of the command of ``ctx`` was given (not its default)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name != "DEFAULT"


def load_mechanism(robot: Path, sidecar: Path | None):
    """The :class:`h4pin.elastic.Mechanism` of ``--robot`` (a URDF and its sidecar, or an MJCF)."""
    from h4pin.elastic import Mechanism

    if not robot.is_file():
        fail(f"--robot: no file {robot}")
    if robot.suffix.lower() == ".xml":
        if sidecar is not None:
            fail("--sidecar goes with a URDF (an MJCF file holds its closures)")
        return Mechanism.from_mjcf(robot)
    return Mechanism.from_urdf(robot, sidecar)


def parse_motors(values: list[str]) -> dict[str, tuple[float, float, int]]:
    """``--motor NAME=LO:HI:N`` options as ``{name: (lo, hi, n)}``."""
    out = {}
    for v in values:
        name, _, spec = v.partition("=")
        parts = spec.split(":")
        try:
            lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
            if len(parts) != 3:
                raise ValueError
        except (ValueError, IndexError):
            fail(f"--motor takes NAME=LO:HI:N (rad or m, N points), got {v!r}")
        if name in out:
            fail(f"--motor {name} is given twice")
        out[name] = (lo, hi, n)
    return out


def _mechanism_scene(robot: Path, sidecar: Path | None, output: str | None, atlas_path: Path | None,
                     stiffness: tuple[float, float] | None, lock: list[str], load: Any, scale: float | None,
                     exaggeration: float | None, host: str) -> Any:
    """``h4pin view --robot FILE``: :func:`h4pin.io.viewer_mechanism.show`; ``stiffness``: the
    (motor, joint) stiffness given (default: the atlas's springs, else 100 and 100)."""
    from h4pin.io import viewer_mechanism
    from h4pin.studies import atlas as atlas_module
    from h4pin.studies import motor_atlas

    ds = atlas_module.open_atlas(atlas_path) if atlas_path is not None else None
    if ds is None and output is None:
        fail("--robot needs --output FRAME (or --atlas PATH, whose output frame is drawn)")
    mech = load_mechanism(robot, sidecar)
    springs = None
    if ds is None or stiffness is not None:
        k = stiffness or (motor_atlas.MOTOR_STIFFNESS, motor_atlas.JOINT_STIFFNESS)
        springs = motor_atlas.default_springs(mech, *k, locked=lock)
    return viewer_mechanism.show(mech, None, springs, output, lock, atlas=ds, load=load, scale=scale,
                                 exaggeration=exaggeration, host=host)


def _motor_atlas(robot: Path, sidecar: Path | None, output: str | None, motor: list[str], count: int | None,
                 motor_k: float, joint_k: float, lock: list[str], threads: int | None, out: Path,
                 figures: Path | None, frequency: bool, quiet: bool, overwrite: bool) -> None:
    """``h4pin atlas --robot FILE``: :func:`h4pin.studies.motor_atlas.atlas`."""
    from h4pin.files import check_output, check_replace
    from h4pin.studies import atlas as atlas_module
    from h4pin.studies import motor_atlas

    if output is None:
        fail("--robot needs --output FRAME (the frame whose compliance is mapped)")
    grid = parse_motors(motor)
    atlas_module.check_out(out, "--out")
    check_replace(out, "--out", overwrite)
    if figures is not None:
        check_output(figures / "atlas_status.png", "--figures")
        for q in ("compliance_max", *(("first_frequency",) if frequency else ()), "status"):
            check_replace(figures / f"atlas_{q}.png", "--figures", overwrite)
    mech = load_mechanism(robot, sidecar)
    springs = motor_atlas.default_springs(mech, motor_k, joint_k, lock)
    axes = motor_atlas.motor_axes(mech, grid, count=count) if count is not None else grid
    ds = motor_atlas.atlas(mech, output, axes, springs, lock, frequency=frequency, threads=threads,
                           progress=not quiet, out=out)
    ok = ds.status == motor_atlas.OK
    typer.echo(f"{mech.name}: {int(ok.sum())} of {ok.size} grid points assembled and restrained "
               f"({', '.join(f'{s} {int((ds.status == c).sum())}' for c, s in enumerate(motor_atlas.STATUS_NAMES))})")
    _atlas_ranges(ds, ok, frequency, f" at {output}", ".4g")
    wrote(out, *(motor_atlas.plot(ds, figures) if figures is not None else ()))


@app.command()
def sweep(
    out: Path = typer.Option(Path("sweep.zarr"), metavar="PATH", help="zarr store of the results (resumed if it "
                             "exists)"),
    designs: int = typer.Option(1000, help="number of designs (Sobol sequence over the design space)"),
    seed: int = typer.Option(0, help="seed of the Sobol sequence"),
    chunk: int = typer.Option(64, help="designs per task (and per zarr chunk)"),
    model: Model = typer.Option("paper", help=f"{MODEL}; both give the same K_tt"),
    workers: int | None = typer.Option(None, help="run on a Dask LocalCluster with this many workers"),
    scheduler: str | None = typer.Option(None, help="run on the Dask scheduler at this address"),
    threads: int | None = typer.Option(None, help="numba threads per task (default: all locally, 1 on Dask)"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH", help="write the Pareto figure to this PNG"),
    urdf_dir: Path | None = typer.Option(None, metavar="DIR", help="write the best designs here as URDF variants"),
    frequency: bool = typer.Option(False, "--frequency",
                                   help="also each design's first natural frequency (Hz): the lowest over the task "
                                   "box's centre and 16 corners that the design reaches, not the box's lowest "
                                   "(a few per cent above it, more where a corner is out of reach; docs/modes.md)"),
    quiet: bool = typer.Option(False, "--quiet", help=QUIET),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
    pareto: Path | None = typer.Option(None, "--pareto", hidden=True, help="old name of --figure"),
) -> None:
    """Design sweep: which designs reach the task box, their worst compliance and workspace volume
    (and first natural frequency)."""
    from h4pin.files import check_output, check_replace
    from h4pin.studies import sweep as sweep_module

    figure, figure_name = renamed(figure, pareto, "--pareto")
    spec = sweep_module.Spec(n_designs=designs, seed=seed, chunk=chunk, model=model, frequency=frequency)
    sweep_module.check_store(out, "--out", overwrite)
    if figure is not None:
        check_output(figure, figure_name, suffixes=(".png",))
        check_replace(figure, figure_name, overwrite)
    if urdf_dir is not None:
        if not urdf_dir.is_dir():
            fail(f"--urdf-dir: folder {urdf_dir} does not exist")
        check_output(urdf_dir / "h4_sweep.urdf", "--urdf-dir")
        for old in sorted(urdf_dir.glob("h4_sweep_*.urdf")):  # the names depend on the results: all that could be
            check_output(old, "--urdf-dir")  # a folder of that name
            check_replace(old, "--urdf-dir", overwrite)
    if workers is not None and workers < 1:
        fail(f"--workers must be >= 1 (Dask workers), got {workers}")
    warn_renamed()
    res = sweep_module.run(out, spec, workers=workers, scheduler=scheduler, threads=threads, progress=not quiet,
                           overwrite=overwrite)
    front = sweep_module.pareto(res)
    typer.echo(f"{res['done'].sum()} of {len(res['done'])} chunks done; {res['valid'].sum()} valid designs, "
               f"{res['reach_all'].sum()} reach the whole task box, {front.size} on the Pareto front")
    for d in front:
        hz = f", first frequency {res['first_frequency'][d]:.1f} Hz" if frequency else ""
        typer.echo(f"  design {d}: worst {res['worst'][d] * 1e6:.1f} um/N, volume {res['volume'][d] * 1e3:.0f} dm^3"
                   f"{hz}")
    wrote(*([sweep_module.plot_pareto(res, figure)] if figure is not None else ()),
          *(sweep_module.write_best(res, urdf_dir) if urdf_dir is not None else ()))


@app.command()
def cycle(
    time: float = typer.Option(0.5, "--time", help="cycle time, s (25 mm up, 305 mm across, 25 mm down and back)"),
    payload: list[float] = typer.Option([0.5], metavar="KG", help=f"{PAYLOAD}; repeat for one column per payload"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH",
                                       help="write trajectory, load, deflection and torques to this PNG"),
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    heading: float = typer.Option(0.0, help="direction of the stroke in the horizontal plane, rad (0: +x)"),
    samples: int = typer.Option(400, help="time steps over the cycle"),
    model: Model = typer.Option(CYCLE_MODEL, help="'consistent' (symmetric K; the cycle's dynamics need it) "
                                "or 'paper' (eq. 30 as printed)"),
    elastic: bool = typer.Option(False, "--elastic", help="also the elastic robot's own answer: the whole robot's "
                                 "loads, its vibration along the cycle and after the stop"),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
) -> None:
    """Tool deflection along the standard pick-and-place cycle (closed-loop inverse dynamics, quasi-static;
    with --elastic, the elastic robot's dynamics too)."""
    from h4pin import limits
    from h4pin.files import check_output, check_replace
    from h4pin.studies import cycle as cycle_module

    if not (math.isfinite(time) and time > 0):
        fail(f"--time must be a finite number > 0 (s), got {time:g}")
    limits.check_range("--time", time, "cycle_time")
    check_payload(payload)
    limits.check_range("--payload", payload, "payload")
    if samples < 8:
        fail(f"--samples must be >= 8, got {samples}")
    limits.check_cycle_samples(samples, len(payload))
    if elastic:  # its motion and the stop after it (sampled at the cycle's step), before the rigid cycle runs
        from h4pin.studies.elastic_cycle import HOLD

        limits.check_elastic_cycle(samples, math.ceil(HOLD / (time / samples)), len(payload))
    check_finite("--heading", (heading,))
    if figure is not None:
        check_output(figure, "--figure", suffixes=(".png",))
        check_replace(figure, "--figure", overwrite)
    h4 = load_robot(variant, urdf)
    results = [cycle_module.run(h4, time, p, samples=samples, model=model, heading=heading) for p in payload]
    typer.echo(cycle_module.report(results))
    if elastic:
        from h4pin.studies import elastic_cycle

        typer.echo("\n" + elastic_cycle.report([elastic_cycle.run(h4, time, p, samples=samples, heading=heading)
                                                for p in payload]))
    if figure is not None:
        wrote(cycle_module.write_figure(results[-1], figure, results[:-1]))


@app.command()
def modes(
    variant: Variant | None = typer.Option(None, help=VARIANT),
    urdf: Path | None = typer.Option(None, help=URDF),
    pose: tuple[float, float, float, float] | None = typer.Option(
        None, metavar="X Y Z THETA", help="pose of D in m and rad (default: all actuators at 45 deg)"),
    payload: float = typer.Option(0.0, metavar="KG", help=PAYLOAD),
    count: int = typer.Option(4, help="how many modes to print"),
    figure: Path | None = typer.Option(None, "--figure", metavar="PATH",
                                       help="write a map of the first frequency over x-y to this PNG"),
    grid: int = typer.Option(21, help="--figure: points per side of the x-y grid"),
    span: float = typer.Option(0.3, help="--figure: side of the x-y grid around the centre, m"),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
    map_png: Path | None = typer.Option(None, "--map", hidden=True, help="old name of --figure"),
) -> None:
    """Natural frequencies of the elastic robot (actuators locked, link inertias from the URDF)."""
    from h4pin import limits

    figure, figure_name = renamed(figure, map_png, "--map")
    check_finite("--pose", pose)
    check_payload(payload)
    limits.check_range("--payload", payload, "payload")
    if count < 1:
        fail(f"--count must be >= 1, got {count}")
    if figure is not None:
        if grid < 2 or not (math.isfinite(span) and span > 0):
            fail(f"--grid must be >= 2 and --span a length > 0 (m), got {grid} and {span:g}")
        from h4pin.files import check_output, check_replace
        from h4pin.studies.frequency import check_size

        check_size(grid * grid, f"modes --grid {grid}")

        check_output(figure, figure_name, suffixes=(".png",))
        check_replace(figure, figure_name, overwrite)
    warn_renamed()
    import numpy as np

    from h4pin.elastic import Payload
    from h4pin.kinematics.closed_form import centre_pose
    from h4pin.vibration import modes as natural_modes

    h4 = load_robot(variant, urdf)
    x = centre_pose(h4) if pose is None else np.array(pose, dtype=float)
    load_ = Payload(payload) if payload > 0 else None
    res = natural_modes(h4, x, load_)
    typer.echo(f"natural modes at x y z theta = {' '.join(f'{v:g}' for v in x)} (m, rad), payload {payload:g} kg")
    typer.echo(f"{'mode':>4}  {'Hz':>8}  plate motion (largest of dD mm, dOmega x 0.1 m)")
    for k in range(min(count, len(res.frequencies))):
        tp = res.shapes_tp[k]
        parts = np.r_[np.abs(tp[:3]), np.abs(tp[3:6]) * 0.1]
        axis = ("x", "y", "z", "rx", "ry", "rz")[int(np.argmax(parts))]
        typer.echo(f"{k + 1:>4}  {res.frequencies[k]:8.1f}  mostly {axis}")
    if figure is not None:
        from h4pin.studies import frequency

        c = centre_pose(h4)
        axis = np.linspace(-span / 2, span / 2, grid)
        ds = frequency.frequency_map(h4, c[0] + axis, c[1] + axis, float(x[2]), float(x[3]), load_)
        f = ds.first_frequency.values
        ok = np.isfinite(f)
        if ok.any():
            typer.echo(f"first frequency over the map: {f[ok].min():.1f} to {f[ok].max():.1f} Hz "
                       f"({int(ok.sum())} of {f.size} poses reachable and regular)")
        else:
            typer.echo(f"first frequency over the map: none of its {f.size} poses is reachable and regular")
        wrote(frequency.plot_map(ds, figure))


@app.command()
def warmup(
    quiet: bool = typer.Option(False, "--quiet", help="print only the total, not each kernel as it compiles"),
) -> None:
    """Compile the compliance kernels into numba's cache now (else the first calls after an install
    use the numpy path while they compile in the background)."""
    from h4pin.warmup import compile_all

    total = compile_all(None if quiet else lambda name, seconds: typer.echo(f"compiled {name} in {seconds:.1f} s"),
                        isolate=True)
    typer.echo(f"compiled code cached ({total:.1f} s)")


#: How docs/cli.md is made (its first line says so).
REGENERATE = ".venv/bin/python -c 'from h4pin.cli import reference; print(reference(), end=\"\")' > docs/cli.md"


def reference() -> str:
    """``docs/cli.md``: every command and option of ``h4pin``, in Markdown, from the click command
    tree of the CLI itself (what ``--help`` prints: the same names, values and defaults), then the
    renamed options (hidden, still taken for one release)."""
    group = typer.main.get_command(app)
    root = group.context_class(group, info_name="h4pin")
    out = [f"<!-- Generated from the CLI by h4pin.cli.reference(); do not edit. Regenerate: {REGENERATE} -->",
           "", "# Command line reference", "",
           f"`h4pin COMMAND [OPTIONS]`: {inspect.cleandoc(group.help or '')} Every command also takes `--help`. "
           "An error prints one line (`error: ...`) and exits with status 2.", "",
           "Conventions: `--out PATH` is a command's main output, `--figure PATH` its picture (PNG), "
           "`--figures DIR` a folder of pictures; an existing file is replaced only if h4pin wrote it, or with "
           "`--overwrite`. `--model` is `paper` unless told (as `h4pin.compliance`; `cycle` aside), `--quiet` hides "
           "progress bars, "
           "`--payload KG` is a point mass at D in kg.", ""]
    old_names = []
    for name, command in group.commands.items():
        ctx = command.context_class(command, info_name=name, parent=root)
        out += [f"## h4pin {name}", "", inspect.cleandoc(command.help or ""), ""]
        for param in command.get_params(ctx):
            if param.name == "help":
                continue
            if getattr(param, "hidden", False):
                old_names += [f"- `h4pin {name} {opt}`: now `{RENAMED[opt]}`" for opt in param.opts]
                continue
            record = param.get_help_record(ctx)
            if record is not None:
                decl, text = record
                out.append(f"- `{decl}`: {text}" if text else f"- `{decl}`")
        out.append("")
    out += ["## Renamed options", "",
            "Still taken for one release, with a one-line warning on stderr; the new name is the one to use.", "",
            *old_names]
    return "\n".join(out) + "\n"


#: Commands that call the compiled kernel directly (the others start on the numpy path while it
#: compiles in the background: h4pin._jit).
COMPILING = ("tolerance", "atlas", "sweep")


def note_first_compile(argv: list[str]) -> None:
    """Say so on stderr before a command whose first run compiles the kernels."""
    if argv and argv[0] in COMPILING and "--help" not in argv and "--robot" not in argv:
        from h4pin.stiffness import kernel

        if not kernel.cached():
            typer.echo("h4pin: first run: compiling the compliance kernels (1-3 min, once; cached afterwards; "
                       "`h4pin warmup` does it ahead)", err=True)


def main() -> None:
    """Entry point of the ``h4pin`` console script: errors are one line and exit status 2."""
    try:
        check_arity(sys.argv[1:])
        note_first_compile(sys.argv[1:])
        code = app(standalone_mode=False)
    except (H4Error, ValueError, FileNotFoundError) as exc:
        typer.echo(f"error: {exc}", err=True)
        sys.exit(2)
    except MemoryError:  # the estimates switched off (H4PIN_MEMORY_LIMIT=0), or wrong: still one line
        typer.echo("error: out of memory: the job does not fit in this machine's memory; make it smaller "
                   "(fewer poses, samples or designs), or set H4PIN_MEMORY_LIMIT to have it refused up front", err=True)
        sys.exit(2)
    except KeyboardInterrupt:
        sys.exit(128 + signal.SIGINT)
    except Stopped as stop:
        sys.exit(128 + stop.signum)
    except Exception as exc:
        if isinstance(exc.__cause__ or exc.__context__, KeyboardInterrupt):  # click's Abort after Ctrl-C
            sys.exit(128 + signal.SIGINT)
        # Usage errors of typer's click (vendored or not): one line instead of a usage box.
        if hasattr(exc, "format_message"):
            if exc.format_message():  # empty after the help printed for a bare `h4pin`
                message = exc.format_message().replace(": Value error, ", ": ")  # typer's coercion says so
                typer.echo(f"error: {message}", err=True)
            sys.exit(2)
        if hasattr(exc, "exit_code"):
            sys.exit(exc.exit_code)
        raise
    sys.exit(code if isinstance(code, int) else 0)


if __name__ == "__main__":
    main()
