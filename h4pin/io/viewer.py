# SPDX-License-Identifier: Apache-2.0
"""The H4 in a browser: its meshes, compliance ellipsoids and deflected shape in h4pin's one
meshcat scene (:class:`h4pin.mechanism.scene.Scene`, drawn here with the H4's numbers).

The viewer only draws: it asks :func:`h4pin.compliance` once per pose and
:mod:`h4pin.stiffness.deflection` for the deflected shape of that compliance.

    from h4pin import load

    from h4pin.io import viewer
    scene = viewer.show(load(), load=[0, 0, -10], field=True)   # starts a meshcat server
    print(scene.url)                                             # open it in a browser
    scene.write_html("h4.html")                                  # self-contained page (offline)
    scene.close()                                                # stops the server

What is drawn, and the scales (also written in the page's legend, ``Scene.legend``):

* the robot at the pose, from the URDF's visual geometry;
* the translational compliance ellipsoid at D: its axes are the eigenvectors of the symmetric
  part of the 3x3 block, its radii the eigenvalues (deflection under a unit force along that
  axis) times ``scale`` (mm drawn per um/N); optionally the rotational one (rad/(N.m) block);
* under a load: a transparent ghost of the deflected robot, exaggerated ``exaggeration`` times,
  and an arrow for the force at D;
* optionally an ellipsoid field over a workspace grid, coloured by the largest translational
  compliance (um/N, viridis; the range is in the legend);
* optionally a natural mode of the elastic robot (:func:`h4pin.modes`), animated and exaggerated
  (:func:`animate_mode`; the static page keeps the animation).
"""

from __future__ import annotations

from typing import Any

import matplotlib
import meshcat
import numpy as np
import pinocchio as pin
from tqdm import tqdm

from h4pin import limits
from h4pin.deprecations import module_getattr
from h4pin.errors import ParameterError
from h4pin.kinematics import closed_form as geometry
from h4pin.kinematics.closed_form import centre_pose
from h4pin.mechanism import meshcat_server
from h4pin.mechanism.engine import output_jacobian
from h4pin.mechanism.scene import ELLIPSOID_SIZE, GHOST_SIZE, Scene, ellipsoid_axes, hex_color, nice
from h4pin.robot import H4
from h4pin.stiffness.api import Compliance, as_load, compliance
from h4pin.stiffness.deflection import deflected_configuration, deflection

__getattr__ = module_getattr(__name__)  # names that moved to h4pin.mechanism.scene (h4pin.deprecations)

#: Where the H4's scene is framed: the point the camera orbits (0.33 m below the actuators) and
#: the camera's offset from it (m, z up).
CENTRE, EYE = np.array([0.0, 0.0, -0.33]), np.array([0.3, -0.78, 0.12])


def scene(h4: H4, vis: meshcat.Visualizer | None = None, host: str = meshcat_server.LOCALHOST) -> Scene:
    """A :class:`~h4pin.mechanism.scene.Scene` of the H4 (its meshes), framed on the robot."""
    s = Scene(h4, vis, host)
    s.frame(CENTRE, EYE)
    return s


def ellipsoid(scene: Scene, pose: np.ndarray, result: Compliance | None = None, model: str = "consistent",
              scale: float | None = None, rotational: bool = False) -> float:
    """Draw the translational (and optionally rotational) compliance ellipsoid at D.

    Args:
        result: the compliance at ``pose`` (:func:`h4pin.compliance`), computed once by the
            caller; default: computed here with ``model``.
        scale: mm drawn per um/N; default: the largest radius is drawn about 120 mm.

    Returns:
        The scale used (mm per um/N).
    """
    x = geometry.as_poses(pose)
    if scale is not None:
        limits.check_range("scale", scale, "scale")
    res = compliance(scene.subject, x, model) if result is None else result
    k = res.matrix
    used = scene.compliance(k[:3, :3], x[:3], scale, where="D")
    scene.legend[-1] += f", model '{res.model}'"
    if rotational:
        rr, ra = ellipsoid_axes(k[3:6, 3:6])
        rscale = ELLIPSOID_SIZE / rr.max()
        scene.ellipsoid("compliance/rotational", x[:3], rr * rscale, ra, 0xe040e0, 0.35)
        scene.legend.append(f"magenta: rotational ellipsoid, 1 urad/(N.m) drawn as {rscale * 1e-3:.3g} mm "
                            f"(radii {', '.join(f'{v * 1e6:.1f}' for v in rr)} urad/(N.m))")
    return used


def ghost(scene: Scene, pose: np.ndarray, load: Any, result: Compliance | None = None,
              model: str = "consistent", exaggeration: float | None = None) -> float:
    """Draw the ghost of the deflected robot under ``load`` (force F (3,) N at D, or Gamma_ext
    (8,)) and an arrow for the force; ``result``: the compliance at ``pose``, computed once by the
    caller (default: computed here). ``exaggeration``: factor on the deflection (default: D moves
    about 30 mm on screen). Returns the exaggeration used."""
    h4 = scene.subject
    x = geometry.as_poses(pose)
    g = as_load(load)
    if exaggeration is not None:
        limits.check_range("exaggeration", exaggeration, "exaggeration")
    dtp, dq = deflection(h4, x, g, model, result=result)
    if exaggeration is None:
        exaggeration = nice(GHOST_SIZE / max(np.linalg.norm(dtp[:3]), 1e-12))
    force = g[:3]
    scene.ghost(deflected_configuration(h4, x, g, scale=exaggeration, model=model, deflected=(dtp, dq)),
                f"red ghost: deflection under F = ({', '.join(f'{f:g}' for f in force)}) N exaggerated "
                f"x{exaggeration:g} (true |dD| = {np.linalg.norm(dtp[:3]) * 1e6:.1f} um)")
    scene.force(x[:3], force)
    return exaggeration


def loaded_ghost(scene: Scene, pose: np.ndarray, load: Any = None, payload: Any = None,
                 exaggeration: float | None = None) -> float:
    """Draw the ghost of the robot in its loaded equilibrium (:mod:`h4pin.studies.loaded`: the
    elastic model under its weight, ``load`` (force F (3,) N at D) and ``payload`` (an
    :class:`h4pin.Payload` at D), the non-linear equilibrium rather than the linear deflection),
    exaggerated (default: D moves about 30 mm on screen), and an arrow for the force. The plate
    moves by the equilibrium's D and rotation, each forearm by its elastic actuator joint. Returns
    the exaggeration."""
    from h4pin.elastic import elastic_model
    from h4pin.kinematics import pinocchio as kin
    from h4pin.kinematics.closed_form import PlateState

    h4 = scene.subject
    x = geometry.as_pose(pose)
    if exaggeration is not None:
        limits.check_range("exaggeration", exaggeration, "exaggeration")
    em = elastic_model(h4)
    force = np.zeros(3) if load is None else as_load(load)[:3]
    eq = em.mechanism.equilibrium(em.configuration(x), {}, {"D": force} if load is not None else None, gravity=True,
                                  payload=None if payload is None else ("D", payload))
    dy = eq.displacement("D")
    dv = pin.difference(em.model, eq.rest, eq.q)
    act = np.array([dv[em.model.joints[em.model.getJointId(f"actuator_{i + 1}_elastic")].idx_v] for i in range(4)])
    d = em.model.createData()
    pin.computeJointJacobians(em.model, d, eq.rest)
    lateral = (output_jacobian(em.model, d, em.outputs) @ dv)[6:8]  # the lateral bars' omega, signed as eq. 30
    if exaggeration is None:
        exaggeration = nice(GHOST_SIZE / max(np.linalg.norm(dy[:3]), 1e-12))
    st = kin.state(h4, x)
    a = exaggeration
    q = kin.assemble(h4, PlateState(st.q + a * act, st.D + a * dy[:3], pin.exp3(a * dy[3:]) @ st.R,
                                    st.omega + a * lateral))
    what = "its weight" + ("" if payload is None else f" and {payload.mass:g} kg at D") + \
        ("" if load is None else f" and F = ({', '.join(f'{f:g}' for f in force)}) N")
    scene.ghost(q, f"red ghost: loaded equilibrium under {what}, exaggerated x{a:g} (true |dD| = "
                   f"{np.linalg.norm(dy[:3]) * 1e6:.1f} um)")
    if load is not None:
        scene.force(x[:3], force)
    return exaggeration


def animate_mode(scene: Scene, pose: np.ndarray, index: int = 0, payload: Any = None, amplitude: float | None = None,
         frames: int = 48, robot: Any = None) -> tuple[float, float]:
    """Animate natural mode ``index`` (0: the first) of the elastic robot at ``pose``
    (:func:`h4pin.modes`), exaggerated, as a meshcat animation (kept by ``scene.html()``).

    The rigid robot is drawn through one period: the plate moves by ``a sin(t) dtp`` of the
    mode and each actuator's forearm by the mode's rotation of its elastic actuator joint
    (actuator + forearm bending); forearm torsion and bar stretch are not drawn (the bars are
    re-aimed at the moved plate).

    Args:
        payload: an :class:`h4pin.Payload` on the plate, or None.
        amplitude: factor on the mass-normalised mode (default: D moves about 30 mm on screen).
        frames: animation frames per period (played at 24 frames/s).
        robot: an :class:`h4pin.ElasticH4` of this robot to reuse (default: built here).

    Returns:
        (frequency in Hz, the amplitude used).
    """
    from h4pin.elastic import elastic_model, modes
    from h4pin.kinematics import pinocchio as kin
    from h4pin.kinematics.closed_form import PlateState

    h4 = scene.subject
    x = geometry.as_pose(pose)
    em = robot if robot is not None else elastic_model(h4)
    res = modes(em, x, payload)
    if not (isinstance(index, int | np.integer) and 0 <= index < len(res.frequencies)):
        raise ParameterError(f"mode index must be an integer in 0..{len(res.frequencies) - 1}, got {index!r}")
    tp = res.shapes_tp[index]
    act = np.array([res.shapes_q[index, em.model.joints[em.model.getJointId(f"actuator_{i + 1}_elastic")].idx_v]
                    for i in range(4)])
    if amplitude is None:
        amplitude = nice(GHOST_SIZE / max(np.linalg.norm(tp[:3]), 1e-12))
    st = kin.state(h4, x)

    def at(f: int) -> np.ndarray:
        a = amplitude * np.sin(2 * np.pi * f / frames)
        return kin.assemble(h4, PlateState(st.q + a * act, st.D + a * tp[:3], pin.exp3(a * tp[3:6]) @ st.R,
                                           st.omega + a * tp[6:8]))

    scene.animate(at(f) for f in range(frames))
    freq = float(res.frequencies[index])
    scene.legend.append(f"animation: mode {index + 1} of the elastic robot, {freq:.1f} Hz"
                        f"{'' if payload is None else f' with a {payload.mass:g} kg payload'}, exaggerated "
                        f"x{amplitude:g} (mass-normalised shape; actuators locked)")
    return freq, amplitude


def ellipsoid_field(scene: Scene, poses: np.ndarray, model: str = "consistent", size: float = 0.025,
          progress: bool = True) -> tuple[float, float]:
    """Ellipsoids at many poses (one batch of :func:`h4pin.compliance`), coloured by the largest
    translational compliance. Unreachable or singular poses are skipped. Every ellipsoid uses one
    scale so that the largest is drawn with radius ``size`` (m).

    Returns:
        The colour range (um/N) of the largest eigenvalue.
    """
    x = geometry.as_poses(poses)
    x = x[None] if x.ndim == 1 else x
    res = compliance(scene.subject, x, model, on_error="nan")
    ok = np.flatnonzero(res.valid)
    if ok.size == 0:
        raise ParameterError("no pose of the field is reachable and regular")
    blocks = [ellipsoid_axes(res.matrix[n, :3, :3]) for n in ok]
    top = np.array([r.max() for r, _ in blocks]) * 1e6
    lo, hi = float(top.min()), float(top.max())
    scale = size / (hi * 1e-6)
    cmap = matplotlib.colormaps["viridis"]
    for n, (radii, axes), t in tqdm(list(zip(ok, blocks, top, strict=True)), desc="ellipsoid field",
                                    unit="pose", disable=not progress):
        colour = hex_color(cmap((t - lo) / (hi - lo) if hi > lo else 0.5))
        scene.ellipsoid(f"field/{n}", x[n, :3], radii * scale, axes, colour, 0.85)
    scene.legend.append(f"field: {ok.size} of {len(x)} poses, largest compliance {lo:.1f} (dark) to "
                        f"{hi:.1f} (yellow) um/N, radius {size * 1e3:g} mm for {hi:.1f} um/N")
    return lo, hi


def workspace_grid(h4: H4, n: int = 5, span: float = 0.2, heights: tuple[float, ...] = (-0.05, 0.05)) -> np.ndarray:
    """Poses (theta = 0) on an n x n grid of side ``span`` (m) around the centre, at the centre's
    height plus each of ``heights`` (m)."""
    c = centre_pose(h4)
    xs = np.linspace(-span / 2, span / 2, n)
    return np.array([[c[0] + a, c[1] + b, c[2] + dz, 0.0] for dz in heights for a in xs for b in xs])


def show(h4: H4, pose: np.ndarray | None = None, load: np.ndarray | None = None, *, scale: float | None = None,
         exaggeration: float | None = None, field: bool = False, rotational: bool = False,
         model: str = "consistent", vis: meshcat.Visualizer | None = None,
         host: str = meshcat_server.LOCALHOST, mode: int | None = None, payload: Any = None,
         result: Compliance | None = None, gravity: bool = False) -> Scene:
    """Draw the H4 at ``pose`` with its compliance ellipsoid, and optionally more. The compliance
    at the pose is computed once (or given: ``result``) and drawn as the ellipsoid and the ghost.

    Args:
        h4: The robot (:func:`h4pin.load`).
        pose: [x, y, z, theta] in m, rad; default: the centre (all actuators at 45 deg).
        load: Force (3,) N at D, or Gamma_ext (8,): draws the deflected ghost and an arrow.
        scale: mm drawn per um/N for the ellipsoid (default: automatic, stated in the legend).
        exaggeration: Factor on the drawn deflection (default: automatic, stated).
        field: Also draw an ellipsoid field over a workspace grid.
        rotational: Also draw the rotational compliance ellipsoid.
        model: "consistent" (default, symmetric K) or "paper".
        vis: Existing meshcat visualizer (e.g. in Jupyter); default: a new server.
        host: Interface a new server listens on (default 127.0.0.1, this machine only).
        mode: Also animate this natural mode of the elastic robot (0: the first; :func:`animate_mode`).
        payload: An :class:`h4pin.Payload` on the plate for ``mode`` and ``gravity``.
        result: the compliance at ``pose`` with ``model`` (:func:`h4pin.compliance`), if the
            caller has it.
        gravity: draw the loaded equilibrium under the robot's weight (with ``load`` and
            ``payload``: :func:`loaded_ghost`) instead of the linear deflection under ``load``.

    Returns:
        The :class:`~h4pin.mechanism.scene.Scene` (``scene.url``, ``scene.write_html(path)``,
        ``scene.close()``).

    Raises:
        UnreachablePoseError, SingularPoseError: as :func:`h4pin.compliance`; no server is left.
    """
    x = centre_pose(h4) if pose is None else geometry.as_poses(pose)
    if x.ndim != 1:
        raise ParameterError(f"show takes one pose (4,), got shape {x.shape}")
    res = compliance(h4, x, model) if result is None else result  # fails before a server starts
    if load is not None:
        as_load(load)
    for name, value in (("scale", scale), ("exaggeration", exaggeration)):
        if value is not None:
            limits.check_range(name, value, name)
    s = scene(h4, vis, host)
    try:
        s.pose(x)
        ellipsoid(s, x, res, model, scale, rotational)
        if gravity:
            loaded_ghost(s, x, load, payload, exaggeration)
        elif load is not None:
            ghost(s, x, load, res, model, exaggeration)
        if field:
            ellipsoid_field(s, workspace_grid(h4), model)
        if mode is not None:
            animate_mode(s, x, mode, payload)
    except BaseException:
        s.close()
        raise
    return s


__all__ = ["CENTRE", "EYE", "animate_mode", "ellipsoid", "ellipsoid_field", "ghost", "loaded_ghost", "scene", "show",
           "workspace_grid"]
