# SPDX-License-Identifier: Apache-2.0
"""The H4 for MuJoCo: an MJCF with the 8 closures as ``connect`` equalities and 4 motors.

MuJoCo reads h4pin's URDF but drops the ``<constraint>`` elements (``neq = 0``): the legs then
hang loose. :func:`to_mjcf` writes the robot from its Pinocchio model instead, one body per
Pinocchio joint (so MuJoCo's ``qpos`` follows Pinocchio's joint order):

- body placements, joint axes and inertias (mass, centre of mass, full inertia) from ``h4.model``
  (Pinocchio has already merged the fixed links into their joints' bodies), the plate's floating
  joint as a ``freejoint``;
- a site for every named frame of the URDF (``D``, ``B_ij``, ``bar_ij_end``, ...);
- each closure as ``<connect site1 site2>`` between its two points (``bar_ij_end`` on the bar,
  ``B_ij`` on the lateral bar), so it does not depend on ``qpos0``; stiff constraint parameters
  (``solref`` 0.5 ms, ``solimp`` 0.999-0.9999) and a 0.1 ms time step keep the loops closed;
- a ``motor`` (torque, N.m, gear 1, no control limit) on each actuated joint, in leg order;
- the visual primitives (cylinders, spheres) as geoms that do not collide;
- a keyframe ``q0``: the centre configuration, loops closed.

:func:`qpos` converts a Pinocchio configuration to MuJoCo's (quaternion w first).
``h4pin export --mjcf PATH`` writes the file.
"""

from __future__ import annotations

import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.files import write_text

#: MuJoCo time step (s) written in the MJCF.
TIMESTEP = 1e-4
#: Constraint softness of the closures: solref (time constant s, damping ratio) and solimp.
SOLREF = (0.0005, 1.0)
SOLIMP = (0.999, 0.9999, 0.001, 0.5, 2.0)


def _f(values) -> str:
    return " ".join(repr(float(v)) for v in np.atleast_1d(values))


def _quat(rotation: np.ndarray) -> str:
    q = pin.Quaternion(np.asarray(rotation))
    return _f([q.w, q.x, q.y, q.z])


def _axis(joint) -> np.ndarray:
    """Rotation axis of a revolute joint, from its motion subspace."""
    jd = joint.createData()
    joint.calc(jd, np.zeros(joint.nq))
    s = jd.S
    s = np.asarray(s.matrix() if hasattr(s, "matrix") else s, float).reshape(6, -1)
    return s[3:, 0]


def _geom(obj, rgba: str) -> str | None:
    geom = obj.geometry
    kind = type(geom).__name__
    place = f'pos="{_f(obj.placement.translation)}" quat="{_quat(obj.placement.rotation)}"'
    sizes = {"Cylinder": lambda: [geom.radius, geom.halfLength], "Sphere": lambda: [geom.radius],
             "Box": lambda: np.asarray(geom.halfSide)}
    if kind not in sizes:
        return None
    return (f'<geom name={quoteattr(obj.name)} type="{kind.lower()}" size="{_f(sizes[kind]())}" {place} '
            f'contype="0" conaffinity="0" mass="0" rgba="{rgba}" group="1"/>')


def to_mjcf(h4, name: str | None = None) -> str:
    """MJCF text of ``h4`` (any variant or :class:`h4pin.H4`): tree, closures, motors, keyframe ``q0``."""
    from h4pin.kinematics.closed_form import centre_pose

    model = h4.model
    name = name or model.name or "h4"
    children: dict[int, list[int]] = {}
    for jid in range(1, model.njoints):
        children.setdefault(model.parents[jid], []).append(jid)
    sites: dict[int, list[str]] = {}
    for f in model.frames:
        if f.type == pin.FrameType.BODY:
            sites.setdefault(f.parentJoint, []).append(
                f'<site name={quoteattr(f.name)} pos="{_f(f.placement.translation)}" '
                f'quat="{_quat(f.placement.rotation)}" size="0.004" group="2"/>')
    geoms: dict[int, list[str]] = {}
    for obj in h4.visual_model.geometryObjects:
        rgba = _f(np.asarray(obj.meshColor))
        text = _geom(obj, rgba)
        if text is not None:
            geoms.setdefault(obj.parentJoint, []).append(text)

    lines: list[str] = []

    def body(jid: int, depth: int) -> None:
        pad = "  " * depth
        joint = model.joints[jid]
        place = model.jointPlacements[jid]
        inertia = model.inertias[jid]
        lines.append(f'{pad}<body name={quoteattr(model.names[jid])} pos="{_f(place.translation)}" '
                     f'quat="{_quat(place.rotation)}">')
        inner = pad + "  "
        i = np.asarray(inertia.inertia)
        full = [i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2]]
        lines.append(f'{inner}<inertial pos="{_f(inertia.lever)}" mass="{inertia.mass!r}" fullinertia="{_f(full)}"/>')
        if joint.nq == 7 and joint.nv == 6:
            if model.parents[jid] != 0:
                raise ParameterError("h4: a floating joint must hang from the world for MuJoCo's freejoint")
            lines.append(f'{inner}<freejoint name={quoteattr(model.names[jid])}/>')
        elif joint.nq == 1 and joint.nv == 1:
            lines.append(f'{inner}<joint name={quoteattr(model.names[jid])} type="hinge" axis="{_f(_axis(joint))}" '
                         'limited="false"/>')
        else:
            raise ParameterError(f"h4: joint '{model.names[jid]}' ({joint.shortname()}) has no MuJoCo counterpart here")
        lines.extend(inner + s for s in geoms.get(jid, []) + sites.get(jid, []))
        for child in children.get(jid, []):
            body(child, depth + 1)
        lines.append(f"{pad}</body>")

    for jid in children.get(0, []):
        body(jid, 2)
    tree = lines

    closures = []
    for cm in h4.constraint_models:
        pair = []
        for jid, placement in ((cm.joint1_id, cm.joint1_placement), (cm.joint2_id, cm.joint2_placement)):
            match = [f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == jid
                     and np.allclose(f.placement.translation, placement.translation, rtol=0, atol=1e-12)]
            if not match:
                raise ParameterError(f"h4: closure '{cm.name}' has no named frame at its point on '{model.names[jid]}'")
            pair.append(match[0])
        closures.append(f'    <connect name={quoteattr(cm.name)} site1={quoteattr(pair[0])} '
                        f'site2={quoteattr(pair[1])}/>')

    world = "\n".join(f"    {s}" for s in geoms.get(0, []) + sites.get(0, []))
    motors = [f'    <motor name={quoteattr(n)} joint={quoteattr(n)} gear="1" ctrllimited="false"/>'
              for n in h4.actuated_joint_names]
    key = qpos(h4, h4.configuration(centre_pose(h4)))
    return "\n".join([
        "<!-- SPDX-License-Identifier: Apache-2.0 -->",
        f"<!-- The H4 parallel robot '{name}', written by h4pin.io.mjcf from its Pinocchio model: "
        "8 loop closures as connect equalities, 4 torque motors (N.m). -->",
        f"<mujoco model={quoteattr(name)}>",
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{TIMESTEP!r}" gravity="{_f(model.gravity.linear)}" integrator="implicitfast"/>',
        f'  <default><equality solref="{_f(SOLREF)}" solimp="{_f(SOLIMP)}"/></default>',
        "  <worldbody>",
        world,
        *tree,
        "  </worldbody>",
        "  <equality>",
        *closures,
        "  </equality>",
        "  <actuator>",
        *motors,
        "  </actuator>",
        "  <keyframe>",
        f'    <key name="q0" qpos="{_f(key)}"/>',
        "  </keyframe>",
        "</mujoco>",
    ]) + "\n"


def qpos(h4, q: np.ndarray) -> np.ndarray:
    """MuJoCo ``qpos`` (nq,) of a Pinocchio configuration of ``h4``: free joints as world pose with
    the quaternion w first (x y z qw qx qy qz); every other joint as is."""
    q = np.asarray(q, float)
    if q.shape != (h4.model.nq,):
        raise ParameterError(f"q: expected shape ({h4.model.nq},), got {q.shape}")
    out = q.copy()
    for jid in range(1, h4.model.njoints):
        j = h4.model.joints[jid]
        if j.nq == 7 and j.nv == 6:
            m = h4.model.jointPlacements[jid] * pin.XYZQUATToSE3(q[j.idx_q:j.idx_q + 7])
            quat = pin.Quaternion(m.rotation)
            out[j.idx_q:j.idx_q + 7] = np.r_[m.translation, quat.w, quat.x, quat.y, quat.z]
    return out


def write_mjcf(h4, path: str | os.PathLike) -> Path:
    """Write :func:`to_mjcf` to ``path`` atomically (a temporary file renamed), mode 0644.

    Raises:
        FileNotFoundError: the folder of ``path`` does not exist.
        IsADirectoryError: ``path`` is a folder.
    """
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(f"path: {path} is a folder")
    if not path.parent.is_dir():
        raise FileNotFoundError(f"path: no folder {path.parent}")
    return write_text(path, to_mjcf(h4, path.stem))


__all__ = ["SOLIMP", "SOLREF", "TIMESTEP", "qpos", "to_mjcf", "write_mjcf"]
