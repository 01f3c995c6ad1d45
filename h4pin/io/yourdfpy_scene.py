# SPDX-License-Identifier: Apache-2.0
"""A yourdfpy scene of an H4 at any pose or configuration, with its loops closed.

yourdfpy (``yourdfpy.URDF``, a core dependency) reads h4pin's URDFs, but its ``update_cfg`` does
not move a ``floating`` joint: it always puts the child at the joint's origin. The H4's central
bar hangs from the base by the floating joint ``plate``, so a scene set through ``update_cfg`` alone
shows the legs at their angles and the plate at the origin, torn open (about 0.59 m at the centre
pose). :func:`pose_scene` sets every revolute and prismatic joint through yourdfpy's own
``update_cfg`` and the floating joint's scene-graph edge by hand, from Pinocchio's configuration.
Then every link's transform in the scene is Pinocchio's frame placement of that link
(``tests/test_yourdfpy.py``: every variant, several poses, 1e-9 m).

- :func:`load_scene`: ``h4``'s URDF as a ``yourdfpy.URDF`` with a scene graph.
- :func:`pose_scene`: set a scene to a pose [x, y, z, theta] or a configuration q (nq,).
- :func:`scene_at`: both at once.
"""

from __future__ import annotations

import io
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.kinematics import pinocchio as kin

if TYPE_CHECKING:
    import yourdfpy

    from h4pin.robot import H4


def load_scene(h4: H4, *, load_meshes: bool = False, build_collision_scene_graph: bool = False) -> yourdfpy.URDF:
    """``h4``'s URDF text as a ``yourdfpy.URDF`` with its scene graph built (at yourdfpy's zero
    configuration, loops open until :func:`pose_scene`).

    Args:
        h4: the robot.
        load_meshes: passed to ``yourdfpy.URDF.load`` (h4pin's URDFs use primitives only).
        build_collision_scene_graph: also build the collision scene (posed too by :func:`pose_scene`).
    """
    import yourdfpy

    return yourdfpy.URDF.load(io.BytesIO(h4.urdf.encode()), build_scene_graph=True, load_meshes=load_meshes,
                              build_collision_scene_graph=build_collision_scene_graph,
                              load_collision_meshes=load_meshes and build_collision_scene_graph)


def _configuration(h4: H4, pose: Any, q: Any) -> np.ndarray:
    if pose is not None and q is not None:
        raise ParameterError("give a pose or a configuration q, not both")
    if q is None:
        if pose is None:
            if h4.q0 is None:
                raise ParameterError("this robot does not assemble at its reference pose: give a pose or q")
            return np.array(h4.q0)
        return h4.configuration(pose)
    return kin.as_configuration(h4, q)


def pose_scene(urdf: yourdfpy.URDF, h4: H4, pose: np.ndarray | None = None, *,
               q: np.ndarray | None = None) -> yourdfpy.URDF:
    """Set the scene of ``urdf`` (a ``yourdfpy.URDF`` of ``h4``'s URDF) to a pose or a configuration.

    Revolute and prismatic joints go through yourdfpy's ``update_cfg`` (``urdf.cfg`` holds their
    values); each floating joint's scene-graph edge (and the collision scene's) is set by hand to
    ``origin @ placement``, the placement from Pinocchio's free-flyer coordinates. ``urdf.cfg``'s six
    entries of a floating joint are left as they were (yourdfpy gives them no meaning), and a later
    ``update_cfg`` with every joint puts the plate back at the origin.

    Args:
        urdf: the scene to set (see :func:`load_scene`); changed in place and returned.
        h4: the robot whose URDF ``urdf`` was read from (joint names must match its model's).
        pose: (4,) [x, y, z, theta] in m and rad; the closed configuration is ``h4.configuration(pose)``.
        q: (nq,) a Pinocchio configuration of ``h4.model`` instead (closed or not, shown as given).
            With neither, ``h4.q0`` (every actuator at 45 deg).

    Returns:
        ``urdf``: ``urdf.get_transform(link)`` is then Pinocchio's placement of the frame ``link``
        (4 x 4, m), world = the URDF's root link.

    Raises:
        ParameterError: both or a bad ``pose``/``q``; ``urdf`` has no scene graph; its joints are
            not ``h4``'s.
        UnreachablePoseError (and its subclasses): ``pose`` cannot be reached.
    """
    if getattr(urdf, "scene", None) is None:
        raise ParameterError("urdf has no scene graph: load it with build_scene_graph=True (see load_scene)")
    qv = _configuration(h4, pose, q)
    model = h4.model
    values: dict[str, float] = {}
    floating: list[tuple[Any, np.ndarray]] = []
    for joint in urdf.robot.joints:
        if joint.type == "fixed" or joint.mimic is not None:
            continue
        if not model.existJointName(joint.name):
            raise ParameterError(f"urdf: joint {joint.name!r} is not in the robot's model (another robot's URDF?)")
        pj = model.joints[model.getJointId(joint.name)]
        qj = qv[pj.idx_q:pj.idx_q + pj.nq]
        if joint.type == "floating":
            if pj.nq != 7:
                raise ParameterError(f"urdf: floating joint {joint.name!r} is not a free-flyer in the model")
            floating.append((joint, pin.XYZQUATToSE3(qj).homogeneous))
        elif joint.type in ("revolute", "prismatic"):
            values[joint.name] = float(qj[0])
        elif joint.type == "continuous":
            values[joint.name] = float(np.arctan2(qj[1], qj[0])) if pj.nq == 2 else float(qj[0])
        else:
            raise ParameterError(f"urdf: joint {joint.name!r} of type {joint.type!r} is not supported")
    urdf.update_cfg(values)
    for joint, placement in floating:
        origin = np.eye(4) if joint.origin is None else joint.origin
        for scene in (urdf.scene, getattr(urdf, "collision_scene", None)):
            if scene is not None:
                scene.graph.update(frame_from=joint.parent, frame_to=joint.child, matrix=origin @ placement)
    return urdf


def scene_at(h4: H4, pose: np.ndarray | None = None, *, q: np.ndarray | None = None,
             load_meshes: bool = False) -> yourdfpy.URDF:
    """A new ``yourdfpy.URDF`` of ``h4`` with its scene at ``pose`` (4,) or ``q`` (nq,) (default
    ``h4.q0``): :func:`load_scene` then :func:`pose_scene`. ``urdf.scene.show()`` draws it."""
    return pose_scene(load_scene(h4, load_meshes=load_meshes), h4, pose, q=q)


__all__ = ["load_scene", "pose_scene", "scene_at"]
