# SPDX-License-Identifier: Apache-2.0
"""``h4pin view``: the H4 (or any closed-loop robot, ``--robot``) in meshcat, served or written as a page."""

from __future__ import annotations

import math
import signal
from pathlib import Path
from typing import Any

import typer

from h4pin.cli.common import (
    JOINT_K,
    MODEL,
    MOTOR_K,
    OVERWRITE,
    PAYLOAD,
    QUIET,
    ROBOT,
    SIDECAR,
    STOP_SIGNALS,
    URDF,
    VARIANT,
    Model,
    Stopped,
    Variant,
    check_finite,
    check_payload,
    fail,
    given,
    load_mechanism,
    load_robot,
    restoring_signals,
    stop_on_signal,
    wrote,
)


@restoring_signals
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
    payload: float = typer.Option(0.0, metavar="KG", help=f"with --mode or --gravity: {PAYLOAD} (with --robot: at "
                                  "--output)"),
    gravity: bool = typer.Option(False, "--gravity", help="draw the loaded equilibrium under the robot's weight (and "
                                 "--load, --payload) instead of the linear deflection (docs/loaded.md)"),
    quiet: bool = typer.Option(False, "--quiet", help=f"{QUIET} (of --field)"),
    overwrite: bool = typer.Option(False, "--overwrite", help=OVERWRITE),
    robot: Path | None = typer.Option(None, metavar="FILE", help=f"{ROBOT}, drawn as sticks at its reference assembly "
                                      "instead of the H4 (--variant ... --mode do not apply)"),
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

    out_name = "--out"
    for sig in STOP_SIGNALS:
        if signal.getsignal(sig) is not signal.SIG_IGN:  # nohup's choice stands
            signal.signal(sig, stop_on_signal)
    from h4pin import limits

    _check_numbers(pose, load, scale, exaggeration)
    if mode is not None and mode < 1:
        fail(f"--mode must be >= 1 (1: the first natural mode), got {mode}")
    check_payload(payload)
    limits.check_range("--payload", payload, "payload")
    if payload > 0 and mode is None and not gravity:
        fail("--payload goes with --mode (the payload of the animated mode) or --gravity (its weight)")
    from h4pin.files import check_output, check_replace
    from h4pin.io import viewer
    from h4pin.mechanism import meshcat_server

    if out is not None:
        if out.is_dir():
            fail(f"{out_name} {out} is a folder: give the path of the page to write, e.g. {out / 'h4.html'}")
        check_output(out, out_name)
        check_replace(out, out_name, overwrite)
    else:
        meshcat_server.check_host(host)

    import numpy as np

    from h4pin.kinematics.closed_form import centre_pose
    from h4pin.mechanism import Payload

    mech_options = ("sidecar", "output", "atlas_path", "motor_stiffness", "joint_stiffness", "lock")
    if robot is not None:
        h4_only = [n for n in ("variant", "urdf", "pose", "field", "rotational", "model", "mode")
                   if given(ctx, n)]
        if h4_only:
            fail(f"--{h4_only[0]} is an option of the H4's view, not of --robot")
        own = any(given(ctx, n) for n in ("motor_stiffness", "joint_stiffness", "lock"))
        scene = _mechanism_scene(robot, sidecar, output, atlas_path, (motor_stiffness, joint_stiffness) if own
                                 else None, lock or [], load, scale, exaggeration, host, (gravity, payload))
    elif extra := [n.replace("_path", "").replace("_", "-") for n in mech_options if given(ctx, n)]:
        fail(f"--{extra[0]} goes with --robot FILE")
    else:
        h4 = load_robot(variant, urdf)
        # The field and the mode are drawn here rather than by viewer.show (same order), for --quiet.
        scene = viewer.show(h4, None if pose is None else list(pose), None if load is None else list(load),
                            scale=scale, exaggeration=exaggeration, rotational=rotational, model=model, host=host,
                            gravity=gravity, payload=Payload(payload) if gravity and payload > 0 else None)
    try:
        if robot is None and field:
            viewer.ellipsoid_field(scene, viewer.workspace_grid(h4), model, progress=not quiet)
        if robot is None and mode is not None:
            x = centre_pose(h4) if pose is None else np.array(pose, dtype=float)
            viewer.animate_mode(scene, x, mode - 1, Payload(payload) if payload > 0 and not gravity else None)
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



def _check_numbers(pose: Any, load: Any, scale: float | None, exaggeration: float | None) -> None:
    """One line for a pose, load, scale or exaggeration that is not a finite, plausible number."""
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


def _mechanism_scene(robot: Path, sidecar: Path | None, output: str | None, atlas_path: Path | None,
                     stiffness: tuple[float, float] | None, lock: list[str], load: Any, scale: float | None,
                     exaggeration: float | None, host: str, loaded: tuple[bool, float] = (False, 0.0)) -> Any:
    """``h4pin view --robot FILE``: :func:`h4pin.mechanism.scene.show`; ``stiffness``: the
    (motor, joint) stiffness given (default: the atlas's springs, else 100 and 100)."""
    from h4pin.mechanism import atlas as motor_atlas
    from h4pin.mechanism import scene, store

    ds = store.open_store(atlas_path) if atlas_path is not None else None
    if ds is None and output is None:
        fail("--robot needs --output FRAME (or --atlas PATH, whose output frame is drawn)")
    mech = load_mechanism(robot, sidecar)
    springs = None
    if ds is None or stiffness is not None:
        k = stiffness or (motor_atlas.MOTOR_STIFFNESS, motor_atlas.JOINT_STIFFNESS)
        springs = motor_atlas.default_springs(mech, *k, locked=lock)
    from h4pin.mechanism import Payload

    gravity, kg = loaded
    return scene.show(mech, None, springs, output, lock, atlas=ds, load=load, scale=scale,
                      exaggeration=exaggeration, host=host, gravity=gravity, payload=Payload(kg) if kg > 0 else None)


