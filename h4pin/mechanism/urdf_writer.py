# SPDX-License-Identifier: Apache-2.0
"""A mechanism as a URDF and its closed-loop sidecar (Gepetto's YAML, h4pin's ``springs:`` key):
what :meth:`Calibration.to_urdf <h4pin.mechanism.calibration.Calibration.to_urdf>` writes, and
what :meth:`Mechanism.from_urdf <h4pin.mechanism.Mechanism.from_urdf>` reads back.

One link per joint (named after the joint's body frame when it has one at the joint's origin,
else ``<joint>_link``), carrying the joint's inertia; every other frame a link of its own on a
fixed joint (``<frame>_fixed``); each closure two frames ``<closure>_1``, ``<closure>_2`` at its
two placements, paired in the sidecar with their type; the motors as ``name_mot``; the springs as
``springs:``. Revolute and prismatic joints only (their axis and origin as Pinocchio holds them),
on a fixed base; a calibration's base pose is put on the root's children, its markers' offsets on
their frames, its joints' offsets in their placements (a coordinate ``q`` of the file is ``q +
offset`` of the mechanism), so the file means the calibrated robot in the tracker's frame.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError, UnsupportedFeatureError
from h4pin.files import check_output, check_replace, write_text


def _axis(jm: Any) -> tuple[str, np.ndarray]:
    """``("revolute" | "prismatic", axis (3,))`` of a one-coordinate joint model."""
    name = jm.shortname()
    for kind, prefix in (("revolute", "JointModelR"), ("prismatic", "JointModelP")):
        if name in (f"{prefix}X", f"{prefix}Y", f"{prefix}Z"):
            return kind, np.eye(3)["XYZ".index(name[-1])]
    if name == "JointModelRevoluteUnaligned":
        return "revolute", np.asarray(jm.extract().axis, float)
    if name == "JointModelPrismaticUnaligned":
        return "prismatic", np.asarray(jm.extract().axis, float)
    raise UnsupportedFeatureError(f"to_urdf: joint model {name} has no URDF counterpart here (revolute and prismatic "
                                  "joints only)")


def _origin(parent: ET.Element, placement: pin.SE3) -> None:
    rpy = pin.rpy.matrixToRpy(placement.rotation)
    ET.SubElement(parent, "origin", xyz=" ".join(repr(float(v)) for v in placement.translation),
                  rpy=" ".join(repr(float(v)) for v in rpy))


def _inertial(link: ET.Element, inertia: pin.Inertia) -> None:
    if inertia.mass <= 0:
        return
    el = ET.SubElement(link, "inertial")
    _origin(el, pin.SE3(np.eye(3), np.asarray(inertia.lever)))
    ET.SubElement(el, "mass", value=repr(float(inertia.mass)))
    i = np.asarray(inertia.inertia)
    ET.SubElement(el, "inertia", ixx=repr(float(i[0, 0])), ixy=repr(float(i[0, 1])), ixz=repr(float(i[0, 2])),
                  iyy=repr(float(i[1, 1])), iyz=repr(float(i[1, 2])), izz=repr(float(i[2, 2])))


def urdf(mech: Any, *, base: pin.SE3 | None = None, markers: Mapping[str, Any] | None = None,
         offsets: np.ndarray | None = None) -> tuple[str, dict[str, Any]]:
    """``(URDF text, the sidecar's content)`` of ``mech`` (module docstring)."""
    model = mech.model
    base = pin.SE3.Identity() if base is None else base
    offsets = np.zeros(model.nq) if offsets is None else np.asarray(offsets, float)
    links = {0: "world_root"}
    for j in range(1, model.njoints):
        if model.joints[j].nq != 1 or model.joints[j].nv != 1:
            raise UnsupportedFeatureError(f"to_urdf: joint {model.names[j]!r} ({model.joints[j].shortname()}) has "
                                          "no URDF counterpart here (revolute and prismatic joints on a fixed base)")
        body = [f.name for f in model.frames if f.parentJoint == j and f.type == pin.FrameType.BODY
                and np.allclose(f.placement.homogeneous, np.eye(4), atol=1e-15)]
        links[j] = body[0] if body else f"{model.names[j]}_link"
    root = [f.name for f in model.frames if f.parentJoint == 0 and f.type == pin.FrameType.BODY]
    links[0] = root[0] if root else links[0]
    robot = ET.Element("robot", name=mech.name)
    for j, name in links.items():
        link = ET.SubElement(robot, "link", name=name)
        if j:
            _inertial(link, model.inertias[j])
    for j in range(1, model.njoints):
        kind, axis = _axis(model.joints[j])
        jm = model.joints[j]
        place = model.jointPlacements[j]
        shift = offsets[jm.idx_q]
        if shift:
            place = place * (pin.SE3(pin.exp3(axis * shift), np.zeros(3)) if kind == "revolute"
                             else pin.SE3(np.eye(3), axis * shift))
        if model.parents[j] == 0:
            place = base * place
        el = ET.SubElement(robot, "joint", name=model.names[j], type=kind)
        _origin(el, place)
        ET.SubElement(el, "parent", link=links[int(model.parents[j])])
        ET.SubElement(el, "child", link=links[j])
        ET.SubElement(el, "axis", xyz=" ".join(repr(float(v)) for v in axis))
        lo, hi = mech.ranges[0][jm.idx_q], mech.ranges[1][jm.idx_q]
        if math.isfinite(lo) and math.isfinite(hi):
            ET.SubElement(el, "limit", lower=repr(float(lo - shift)), upper=repr(float(hi - shift)), effort="1000",
                          velocity="100")
        else:
            ET.SubElement(el, "limit", lower="-1e10", upper="1e10", effort="1000", velocity="100")
    named = set(links.values())
    extra = []
    for f in model.frames:
        if f.type == pin.FrameType.JOINT or f.name in named or f.name == "universe" or f.name.endswith("_fixed"):
            continue
        place = f.placement * pin.SE3(np.eye(3), np.asarray((markers or {}).get(f.name, np.zeros(3)), float))
        if f.parentJoint == 0:
            place = base * place
        extra.append((f.name, int(f.parentJoint), place))
    closures, types = [], []
    for cm in mech.constraint_models:
        for side, (jid, place) in enumerate(((cm.joint1_id, cm.joint1_placement), (cm.joint2_id, cm.joint2_placement)),
                                            start=1):
            extra.append((f"{cm.name}_{side}", int(jid), base * place if jid == 0 else place))
        closures.append([f"{cm.name}_1", f"{cm.name}_2"])
        types.append("6d" if cm.type == pin.ContactType.CONTACT_6D else "3d")
    for name, jid, place in extra:
        ET.SubElement(robot, "link", name=name)
        el = ET.SubElement(robot, "joint", name=f"{name}_fixed", type="fixed")
        _origin(el, place)
        ET.SubElement(el, "parent", link=links[jid])
        ET.SubElement(el, "child", link=name)
    ET.indent(robot)
    side = {"closed_loop": closures, "type": types, "name_mot": list(mech.actuated),
            "gravity": [float(v) for v in base.rotation @ model.gravity.linear]}
    return ET.tostring(robot, encoding="unicode") + "\n", side


def write(mech: Any, path: Any, sidecar: Any = None, *, springs: Mapping[str, float] | None = None,
          base: pin.SE3 | None = None, markers: Mapping[str, Any] | None = None, offsets: np.ndarray | None = None,
          overwrite: bool = False) -> tuple[Path, Path]:
    """Write :func:`urdf` to ``path`` (``.urdf``) and the sidecar (default ``path`` with ``.yaml``)
    with ``springs``, atomically; an existing file is replaced only if h4pin wrote it, or with
    ``overwrite``.

    Raises:
        ParameterError: a path that cannot be written. UnsupportedFeatureError: a joint URDF
            cannot state.
    """
    path = check_output(path, "path", suffixes=(".urdf",))
    side_path = check_output(path.with_suffix(".yaml") if sidecar is None else sidecar, "sidecar",
                             suffixes=(".yaml", ".yml"))
    if side_path == path:
        raise ParameterError("sidecar: another file than the URDF")
    for p, what in ((path, "path"), (side_path, "sidecar")):
        check_replace(p, what, overwrite)
    text, side = urdf(mech, base=base, markers=markers, offsets=offsets)
    if springs:
        side["springs"] = {str(k): float(v) for k, v in springs.items()}
        internal = [n for n in springs if n in mech.beam_springs]
        if internal:
            side["elastic"] = internal
    lines = [f"{key}: {_yaml(value)}" for key, value in side.items()]
    write_text(path, text)
    write_text(side_path, "\n".join(lines) + "\n", comment="#")
    return path, side_path


def _yaml(value: Any) -> str:
    """A flow-style YAML value: lists, mappings of names to numbers, numbers and names."""
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"'{k}': {float(v)!r}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_yaml(v) for v in value) + "]"
    if isinstance(value, str):
        return f"'{value}'"
    return repr(float(value))


__all__ = ["urdf", "write"]
