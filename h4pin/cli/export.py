# SPDX-License-Identifier: Apache-2.0
"""``h4pin export``: the H4 (or any closed-loop robot's elastic model) as MuJoCo MJCF."""

from __future__ import annotations

from pathlib import Path

import typer

from h4pin.cli.common import OVERWRITE, URDF, VARIANT, Variant, fail, is_number, load_mechanism, load_robot, wrote


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
) -> None:
    """Export the robot for another tool: --out PATH writes a MuJoCo model (8 closures, 4 motors;
    with --elastic, the compliances as spring joints and the actuators locked, or with --servo
    driven by position servos); --robot PATH --elastic: any closed-loop robot, its springs as
    joint stiffness."""
    from h4pin.files import check_output, check_replace
    from h4pin.io.mjcf import write_mjcf

    out_name = "--out"
    if out is None:
        fail("Missing option '--out'.")
    if servo and not elastic:
        fail("--servo needs --elastic (only the elastic robot has servos)")
    check_output(out, out_name)
    check_replace(out, out_name, overwrite)
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
    springs: dict[str, float] = {}
    for item in spring or []:
        joint, _, value = item.partition("=")
        if not joint or not is_number(value):
            fail(f"--spring takes JOINT=K (K in N.m/rad or N/m), got {item!r}")
        springs[joint] = float(value)
    mech = load_mechanism(robot, sidecar)
    return mech.to_mjcf(out, springs or dict(mech.springs), mech.assemble(), sites=sites, timestep=timestep,
                        overwrite=overwrite)


