# SPDX-License-Identifier: Apache-2.0
"""The H4 as a Pinocchio model with loop closures: :func:`load` and :class:`H4`.

``load("prototype")`` returns an :class:`H4` holding a plain ``pin.Model`` (a tree: base, four
legs with universal joints, and the plate as a floating subtree), its geometry models, and the
eight Pinocchio 3-D point constraints (``pin.RigidConstraintModel``, ``CONTACT_3D``) that close
the bars on the plate. Everything else in h4pin is computed from these.

Velocity split: the 4 actuated joints ``v_a`` and the 24 passive ones ``v_p`` (16 bar
revolutes, 6 plate free-flyer, 2 lateral revolutes). The 24 closure equations
``Jc_a v_a + Jc_p v_p = 0`` have a square 24x24 passive block away from singularities, so the
passive velocities follow from the actuated ones: ``v_p = -Jc_p^-1 Jc_a v_a``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np
import pinocchio as pin

from h4pin import geometry
from h4pin.errors import MalformedURDFError, SingularPoseError
from h4pin.params import LEG_LATERAL, VARIANTS, H4Params
from h4pin.urdf import bar_names, closures_from_urdf, lateral_names, leg_names, params_from_urdf, to_urdf

#: Frames every H4 URDF names (massless links on fixed joints, see :mod:`h4pin.urdf`).
REQUIRED_FRAMES = (["D", "C_1", "C_2"] + [f"{p}_{i}" for p in "PAB" for i in range(1, 5)]
                   + [f"{p}_{i}{j}" for p in "AB" for i in range(1, 5) for j in (1, 2)])

#: Condition number of the passive closure Jacobian above which a pose is called singular.
SINGULAR_COND = 1e10


def urdf_dir() -> Path:
    """Folder of the shipped URDF files (inside the installed package, or the repo's ``urdf/``)."""
    packaged = Path(str(resources.files("h4pin"))) / "urdf"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parent.parent / "urdf"


def variant_path(name: str) -> Path:
    """Path of the shipped URDF of variant ``name`` (``urdf/h4_<name>.urdf``)."""
    return urdf_dir() / f"h4_{name}.urdf"


def load(source: str | Path | H4Params = "prototype") -> H4:
    """Load an H4: a variant name, a path to a URDF file, or an :class:`H4Params`.

    Args:
        source: ``"prototype"`` (default) or ``"symmetric"`` (see :data:`h4pin.VARIANTS`), a path
            to a URDF written by :func:`h4pin.urdf.to_urdf`, or parameters (the URDF is then
            generated in memory).

    Raises:
        ValueError: unknown variant name (the message lists the available ones).
        FileNotFoundError: the path does not exist.
        MalformedURDFError: the URDF does not describe an H4 completely.
    """
    if isinstance(source, H4Params):
        return H4(source, to_urdf(source), "<H4Params>")
    text_source = str(source)
    looks_like_path = isinstance(source, Path) or text_source.endswith(".urdf") or "/" in text_source
    if not looks_like_path:
        if text_source not in VARIANTS:
            raise ValueError(f"unknown H4 variant {text_source!r}; available: {', '.join(sorted(VARIANTS))} "
                             "(or pass a path to a URDF, or an H4Params)")
        path = variant_path(text_source)
    else:
        path = Path(source)
    if not path.is_file():
        raise FileNotFoundError(f"no URDF file at {path}")
    text = path.read_text()
    return H4(params_from_urdf(text, str(path)), text, str(path))


class H4:
    """An H4 robot: Pinocchio model, geometry models, closures and parameters.

    Attributes:
        params: The :class:`H4Params` the URDF encodes.
        model, data: Pinocchio model (nq = 29, nv = 28) and its data.
        visual_model, collision_model: Pinocchio geometry models (primitives).
        constraint_models, constraint_datas: the 8 ``CONTACT_3D`` closures, bar ij at B_ij,
            in the order 11, 12, 21, ..., 42 (index n = 2(i-1) + (j-1)).
        frames: Frame ids by name: P_i, A_i, A_ij, B_i, B_ij, C_k, D, bar_ij_end.
        v_act, v_pas: Velocity indices of the 4 actuators and of the 24 passive joints.
        urdf: The URDF text; source: where it came from.
    """

    def __init__(self, params: H4Params, urdf_text: str, source: str = "URDF"):
        self.params = params
        self.urdf = urdf_text
        self.source = source
        try:
            self.model = pin.buildModelFromXML(urdf_text)
            self.visual_model = pin.buildGeomFromUrdfString(self.model, urdf_text, pin.GeometryType.VISUAL)
            self.collision_model = pin.buildGeomFromUrdfString(self.model, urdf_text, pin.GeometryType.COLLISION)
        except (RuntimeError, ValueError) as exc:
            raise MalformedURDFError(f"{source}: Pinocchio cannot load it ({exc})") from None
        self.data = self.model.createData()
        self.frames = {f.name: i for i, f in enumerate(self.model.frames)}
        self._jid = {name: i for i, name in enumerate(self.model.names)}
        missing = [n for n in REQUIRED_FRAMES if n not in self.frames]
        if missing:
            raise MalformedURDFError(f"{source}: frame(s) {', '.join(missing)} missing (see h4pin.urdf)")

        def jidx(name: str) -> pin.JointModel:
            return self.model.joints[self._jid[name]]

        self.v_act = np.array([jidx(leg_names(i + 1)["joint"]).idx_v for i in range(4)])
        self.v_pas = np.setdiff1d(np.arange(self.model.nv), self.v_act)
        self._q_act = np.array([jidx(leg_names(i + 1)["joint"]).idx_q for i in range(4)])
        self._q_u = np.array([[jidx(bar_names(i + 1, j + 1)[u]).idx_q for u in ("u1", "u2")]
                              for i in range(4) for j in range(2)])
        self._q_plate = jidx("plate").idx_q
        self._v_plate = np.r_[jidx("plate").idx_v + np.arange(6),
                              [jidx(lateral_names(k + 1)["joint"]).idx_v for k in range(2)]]
        self._q_lat = np.array([jidx(lateral_names(k + 1)["joint"]).idx_q for k in range(2)])
        self._build_constraints()
        order = [bar_names(i + 1, j + 1) for i in range(4) for j in range(2)]
        self._fid_D = self.frames["D"]
        #: Frame ids of D, C_k, B_i, B_ij, P_i, A_i, A_ij in this order (31 frames).
        self.point_frames = [self.frames[n] for n in (
            ["D", "C_1", "C_2"] + [f"B_{i}" for i in range(1, 5)] + [b["B"] for b in order]
            + [f"P_{i}" for i in range(1, 5)] + [f"A_{i}" for i in range(1, 5)] + [b["A"] for b in order])]
        self._jid_lat = [self._jid[lateral_names(k + 1)["joint"]] for k in range(2)]
        self._jid_act = [self._jid[leg_names(i + 1)["joint"]] for i in range(4)]
        self._bar_lat = np.repeat(LEG_LATERAL, 2)
        parents = [self.model.frames[f].parentJoint for f in self.point_frames]
        self._point_joints = sorted(set(parents))
        self._point_joint_index = np.array([self._point_joints.index(j) for j in parents])
        self._point_local = np.array([self.model.frames[f].placement.translation for f in self.point_frames])
        # Per-bar constants of assemble: B_ij - C_k in the frame of lateral bar k, u_i and a_i.
        self._b_local = (params.plate_ball_centres() - params.DC.T[LEG_LATERAL][:, None, :]).reshape(8, 3)
        self._u_bar = np.repeat(params.U.T, 2, axis=0)
        self._a_bar = np.repeat(params.forearm_dirs.T, 2, axis=0)
        self._q_neutral = pin.neutral(self.model)

    @property
    def actuated_joint_names(self) -> tuple[str, ...]:
        """Names of the 4 actuated joints in ``model.names``, in leg order (1, 2, 3, 4)."""
        return tuple(leg_names(i + 1)["joint"] for i in range(4))

    def _build_constraints(self) -> None:
        closures = {c[0]: c for c in closures_from_urdf(self.urdf, self.source)}
        self.constraint_models = pin.StdVec_RigidConstraintModel()
        for i in range(4):
            for j in range(2):
                name = bar_names(i + 1, j + 1)["closure"]
                if name not in closures:
                    raise MalformedURDFError(f"{self.source}: loop closure '{name}' is missing")
                _, parent, pxyz, child, cxyz = closures[name]
                sides = []
                for link, xyz in ((parent, pxyz), (child, cxyz)):
                    if link not in self.frames:
                        raise MalformedURDFError(f"{self.source}: closure '{name}' names unknown frame '{link}'")
                    f = self.model.frames[self.frames[link]]
                    sides += [f.parentJoint, f.placement * pin.SE3(np.eye(3), xyz)]
                cm = pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, self.model, *sides, pin.ReferenceFrame.LOCAL)
                cm.name = name
                self.constraint_models.append(cm)
        self.constraint_datas = pin.StdVec_RigidConstraintData()
        for cm in self.constraint_models:
            self.constraint_datas.append(cm.createData())

    # ----------------------------------------------------------------- geometry
    def inverse_geometry(self, pose: np.ndarray, *, on_error: str = "raise") -> np.ndarray:
        """Actuator angles (rad) of pose [x, y, z, theta] (m, rad); (4,) -> (4,), (N, 4) -> (N, 4).

        Closed form, elbow-out branch (see :func:`h4pin.geometry.inverse_geometry`).

        Raises:
            UnreachablePoseError: a leg cannot reach its plate point (the message names the leg).
        """
        return geometry.inverse_geometry(self.params, pose, on_error=on_error)

    def forward_geometry(self, q: np.ndarray, guess: np.ndarray | None = None) -> np.ndarray:
        """Pose [x, y, z, theta] (m, rad) of actuator angles q (4,), by Newton.

        Raises:
            ConvergenceError: the legs do not assemble (or Newton failed from ``guess``).
        """
        return geometry.forward_geometry(self.params, q, guess)

    def configuration(self, pose: np.ndarray, q_act: np.ndarray | None = None) -> np.ndarray:
        """Full Pinocchio configuration (nq,) of a rigid pose, all 8 closures satisfied.

        Actuators from the inverse geometry; each bar's universal joint from the direction of
        B_ij - A_ij in the forearm frame (closed form); plate free-flyer at D with orientation
        Rz(theta); lateral joints at omega_k = -theta (the lateral bars only translate).
        ``q_act`` (4,), the actuator angles of ``pose``, saves an inverse geometry when known.
        """
        x = geometry.as_poses(pose)
        if x.ndim != 1:
            raise ValueError(f"configuration takes a single pose (4,), got shape {x.shape}")
        if q_act is None:
            q_act = self.inverse_geometry(x)
        return self._configuration(x, q_act)

    def _configuration(self, x: np.ndarray, q_act: np.ndarray) -> np.ndarray:
        rot = geometry.rot_z(x[3])
        return self.assemble(q_act, x[:3], rot, np.array([-x[3], -x[3]]))

    def assemble(self, q_act: np.ndarray, d: np.ndarray, rotation: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """Configuration (nq,) with given actuator angles and plate placement; bars aimed at B_ij.

        Args:
            q_act: (4,) actuator angles, rad.
            d: (3,) position of D, m.
            rotation: (3, 3) world orientation of the central bar (Rz(theta) at a rigid pose).
            omega: (2,) joint angles of the lateral bars, rad (-theta at a rigid pose).

        Each bar's universal joint points the bar from A_ij to B_ij (closed form); the closures
        hold exactly when the plate placement is consistent with q_act (e.g. from
        :meth:`configuration`), and approximately for a slightly deformed robot (used to draw
        deflected shapes).
        """
        p = self.params
        _, Aij = geometry.forearm_points(p, np.asarray(q_act, float))
        lat = rotation @ geometry.rot_z(np.asarray(omega, float))  # (2, 3, 3)
        ck = d + (rotation @ p.DC).T  # C_k, (2, 3)
        k = self._bar_lat
        Bij = ck[k] + np.einsum("nab,nb->na", lat[k], self._b_local)
        u, a = self._u_bar, self._a_bar
        qb = np.repeat(q_act, 2)
        w = Bij - Aij.reshape(8, 3)
        w = w / np.sqrt(np.sum(w * w, axis=1, keepdims=True))
        # Bar direction in the forearm frame: Rot(u, -q) w (Rodrigues).
        c, s = np.cos(qb)[:, None], np.sin(qb)[:, None]
        uw = np.sum(u * w, axis=1, keepdims=True)
        bar = w * c - geometry.cross(u, w) * s + u * uw * (1 - c)
        # bar = u sin(beta) - cos(beta) (a sin(alpha) + z cos(alpha))
        beta = np.arcsin(np.clip(np.sum(bar * u, axis=1), -1.0, 1.0))
        alpha = np.arctan2(-np.sum(bar * a, axis=1), -bar[:, 2])
        q = self._q_neutral.copy()
        q[self._q_act] = q_act
        q[self._q_u[:, 0]] = alpha
        q[self._q_u[:, 1]] = beta
        q[self._q_plate:self._q_plate + 7] = pin.SE3ToXYZQUAT(pin.SE3(rotation, np.asarray(d, float)))
        q[self._q_lat] = omega
        return q

    def closure_residuals(self, q: np.ndarray) -> np.ndarray:
        """Position errors of the 8 closures at configuration q, (8, 3) in m, from Pinocchio."""
        pin.forwardKinematics(self.model, self.data, q)
        out = np.empty((8, 3))
        for n, (cm, cd) in enumerate(zip(self.constraint_models, self.constraint_datas, strict=True)):
            cm.calc(self.model, self.data, cd)
            out[n] = cd.c1Mc2.translation
        return out

    # ---------------------------------------------------------------- Jacobians
    def compute(self, q: np.ndarray) -> None:
        """Run Pinocchio's kinematics, joint Jacobians, frames and closures at configuration q."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        for cm, cd in zip(self.constraint_models, self.constraint_datas, strict=True):
            cm.calc(self.model, self.data, cd)

    def passive_map(self) -> np.ndarray:
        """``S`` (nv, 4) with ``v = S q_dot``: the closed-loop velocity of every joint.

        From the closure Jacobian after :meth:`compute`: ``v_p = -Jc_p^-1 Jc_a q_dot``.

        Raises:
            SingularPoseError: the 24x24 passive closure block is singular (cond > 1e10).
        """
        jc = pin.getConstraintsJacobian(self.model, self.data, self.constraint_models, self.constraint_datas)
        jp, ja = jc[:, self.v_pas], jc[:, self.v_act]
        try:
            inv = np.linalg.inv(jp)
            cond = np.abs(jp).sum(0).max() * np.abs(inv).sum(0).max()  # 1-norm condition number
        except np.linalg.LinAlgError:
            cond = np.inf
        if not cond < SINGULAR_COND:
            raise SingularPoseError(f"the passive closure Jacobian is singular (cond = {cond:.2e}): "
                                    "the plate has an uncontrolled motion at this pose")
        s = np.zeros((self.model.nv, 4))
        s[self.v_act] = np.eye(4)
        s[self.v_pas] = -inv @ ja
        return s

    def jacobian(self, pose: np.ndarray) -> np.ndarray:
        """J (4, 4) with x_dot = J q_dot (eq. 8), from Pinocchio's closure and frame Jacobians.

        The passive velocities come from the closure Jacobians (:meth:`passive_map`); the plate
        motion from the frame Jacobian of D (LOCAL_WORLD_ALIGNED), rows v_x, v_y, v_z, w_z.
        """
        self.compute(self.configuration(pose))
        return self.plate_velocity_jacobian()

    def plate_velocity_jacobian(self) -> np.ndarray:
        """J (4, 4) of eq. 8 at the configuration of the last :meth:`compute`."""
        jd = pin.getFrameJacobian(self.model, self.data, self._fid_D, pin.LOCAL_WORLD_ALIGNED)
        return jd[[0, 1, 2, 5]] @ self.passive_map()

    def jx_jq(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The paper's Jx and Jq of eq. 8 (closed form), ``Jx x_dot = Jq q_dot``."""
        x = geometry.as_poses(pose)
        return geometry.jx_jq(self.params, x, self.inverse_geometry(x))

    def plate_jacobians(self, points: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """After :meth:`compute`: Jacobians of the B_ij (8, 3, 8) and A_ij (8, 3, 4) points.

        ``dB_ij = JB[n] dtp`` with ``dtp = [dD, dOmega, domega_1, domega_2]`` (world-aligned at
        D, relative lateral rotations), and ``dA_ij = JA[n] dq`` for actuator rotations. Both are
        Pinocchio Jacobians (LOCAL_WORLD_ALIGNED): the joint Jacobians of the lateral bars and
        forearms, shifted to the points (``v_X = v_joint + w x (X - joint)``); the plate columns
        are mapped from the free-flyer's local velocity to dtp with the frame Jacobian of D.
        ``points``: :meth:`frame_points`, if already computed.
        """
        m, d = self.model, self.data
        lwa = pin.LOCAL_WORLD_ALIGNED
        jd = pin.getFrameJacobian(m, d, self._fid_D, lwa)[:, self._v_plate]
        to_tp = np.eye(8)
        to_tp[:6, :6] = jd[:, :6]  # dtp[:6] = J_D,ff v_ff; lateral columns are identity
        jlat = np.stack([pin.getJointJacobian(m, d, j, lwa)[:, self._v_plate] for j in self._jid_lat])
        jact = np.stack([pin.getJointJacobian(m, d, j, lwa)[:, self.v_act] for j in self._jid_act])
        pts = self.frame_points() if points is None else points
        bij, aij = pts[7:15], pts[23:31]
        jl, ja = jlat[self._bar_lat], jact[np.arange(8) // 2]
        jb = jl[:, :3] - _cross_columns(bij - pts[1:3][self._bar_lat], jl[:, 3:])
        ja = ja[:, :3] - _cross_columns(aij - pts[15:19][np.arange(8) // 2], ja[:, 3:])
        return jb @ np.linalg.inv(to_tp), ja

    def frame_points(self) -> np.ndarray:
        """World positions (31, 3) of the frames D, C_k, B_i, B_ij, P_i, A_i, A_ij (in this order)
        after :meth:`compute`: Pinocchio's joint placements applied to the frames' placements."""
        rot = np.array([self.data.oMi[j].rotation for j in self._point_joints])
        pos = np.array([self.data.oMi[j].translation for j in self._point_joints])
        return pos[self._point_joint_index] + np.einsum("nab,nb->na", rot[self._point_joint_index], self._point_local)

    def frame_position(self, name: str) -> np.ndarray:
        """World position (3,) of a named frame after :meth:`compute` (or forwardKinematics +
        updateFramePlacements)."""
        return self.data.oMf[self.frames[name]].translation.copy()

    # ---------------------------------------------------------------- statics
    def gravity_torques(self, pose: np.ndarray, gravity: np.ndarray | None = None) -> np.ndarray:
        """Actuator torques (4,) in N.m that hold the robot still at ``pose`` under gravity.

        From Pinocchio's generalized gravity ``g(q)`` (nv) and the closure Jacobians: with
        ``v = S q_dot`` (:meth:`passive_map`), virtual work gives ``tau = S^T g(q)``; this is the
        same as eliminating the closure forces ``lambda`` from ``g = tau_full + Jc^T lambda``.
        """
        q = self.configuration(pose)
        if gravity is not None:
            saved = self.model.gravity.linear.copy()
            self.model.gravity.linear = np.asarray(gravity, float)
        try:
            g = pin.computeGeneralizedGravity(self.model, self.data, q)
            self.compute(q)
            return self.passive_map().T @ g
        finally:
            if gravity is not None:
                self.model.gravity.linear = saved

    def potential_energy(self, pose: np.ndarray) -> float:
        """Gravitational potential energy (J) of the assembled robot at ``pose``, from Pinocchio."""
        return float(pin.computePotentialEnergy(self.model, self.data, self.configuration(pose)))

    def __repr__(self) -> str:
        return (f"H4(source={self.source!r}, nq={self.model.nq}, nv={self.model.nv}, "
                f"closures={len(self.constraint_models)})")


def _cross_columns(r: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``r[n] x cols[n, :, c]`` for every n and column c: (n, 3) x (n, 3, m) -> (n, 3, m)."""
    rx, ry, rz = (r[:, i, None] for i in range(3))
    cx, cy, cz = cols[:, 0], cols[:, 1], cols[:, 2]
    return np.stack([ry * cz - rz * cy, rz * cx - rx * cz, rx * cy - ry * cx], axis=1)


__all__ = ["H4", "load", "urdf_dir", "variant_path", "LEG_LATERAL"]
