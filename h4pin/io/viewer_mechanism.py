# SPDX-License-Identifier: Apache-2.0
"""Any closed-loop robot in the browser: its stick drawing (:class:`h4pin.io.viewer.MechanismScene`),
the ellipsoid field of its motor-space atlas, and its deflected shape under a load at the output.

    from h4pin.elastic import Mechanism
    from h4pin.io import viewer_mechanism
    from h4pin.studies import atlas, motor_atlas

    delta = Mechanism.from_urdf("tests/robots/robot_delta/robot.urdf")
    ds = motor_atlas.atlas(delta, "eff")
    with viewer_mechanism.show(delta, atlas=ds, load=[0, -10, 0]) as scene:
        scene.write_html("delta.html")

What is drawn (and stated in the page's legend):

* the robot at q (default: the reference assembly): joints as balls (motors yellow), links as
  rods between joint origins, closure points red;
* with ``atlas`` (a :mod:`h4pin.studies.motor_atlas` Dataset: the viewer reads the store, it
  computes nothing of it): at each grid point of status 0, the compliance ellipsoid of the output
  frame at that point's position (radii: the eigenvalues of C_tt, axes its eigenvectors, one scale
  for all so that the largest is ``size``), coloured by the worst compliance (viridis);
* with ``load`` (force (3,) N, or wrench (6,) N and N.m at the output frame's origin, world
  axes): the deflected robot as a red ghost, exaggerated, and an arrow for the force. The joint
  deflections are ``dq = C_qw w`` (:func:`joint_deflection`), the block of the compliance that
  maps the output's wrench to the joints' motions (reciprocity: the same matrix read as the
  output's motion under joint torques).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from typing import Any

import matplotlib
import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.io import meshcat_server
from h4pin.io.viewer import GHOST_SIZE, MechanismScene, draw_mechanism, hex_color, nice

#: At most this many ellipsoids are drawn (a page of a few MB).
MAX_ELLIPSOIDS = 5000


def _wrench(load: Any) -> np.ndarray:
    w = np.asarray(load, dtype=float).reshape(-1)
    if w.shape not in ((3,), (6,)) or not np.all(np.isfinite(w)):
        raise ParameterError(f"load: a force (3,) N or a wrench (6,) N and N.m, finite, got {load!r}")
    return np.r_[w, np.zeros(6 - len(w))]


def joint_deflection(mech: Any, q: Any, springs: Mapping[str, Any], output: str, load: Any,
                     locked: Iterable[Any] = ()) -> tuple[np.ndarray, np.ndarray]:
    """``(dq (nv,), dy (6,))``: the joint motions and the output frame's motion (translation of
    its origin m, rotation rad, world axes) under ``load`` at the output frame's origin (force
    (3,) N or wrench (6,) N, N.m, world axes), from one compliance with the output frame and every
    joint as outputs (:meth:`h4pin.elastic.Mechanism.compliance`): ``dq = C[6:, :6] w``,
    ``dy = C[:6, :6] w``. The deflected configuration is ``pin.integrate(model, q, dq)``."""
    from h4pin.elastic.engine import JointOutput

    w = _wrench(load)
    names = list(mech.model.names)[1:]
    C = mech.compliance(q, springs, [output, *(JointOutput(n) for n in names)], locked)
    return C[6:, :6] @ w, C[:6, :6] @ w


def field_points(ds: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(positions (n, 3) m, radii (n, 3) m/N, axes (n, 3, 3), worst (n,) m/N)`` of the grid
    points of status 0 of a motor-space atlas (:mod:`h4pin.studies.motor_atlas`), read as stored."""
    if ds.attrs.get("kind") != "mechanism" or "compliance_axes" not in ds:
        raise ParameterError("atlas: a motor-space atlas (h4pin.studies.motor_atlas), with compliance_axes")
    ok = (ds.status.values == 0).reshape(-1)
    n = ok.size
    pos = ds.position.values.reshape(n, 3)[ok]
    radii = ds.compliance_axes.values.reshape(n, 3)[ok]
    axes = ds.compliance_vectors.values.reshape(n, 3, 3)[ok]
    return pos, radii, axes, ds.compliance_max.values.reshape(n)[ok]


def draw_field(scene: MechanismScene, ds: Any, size: float | None = None, path: str = "field") -> tuple[float, float]:
    """The ellipsoid field of a motor-space atlas (:func:`field_points`) into ``scene``: one
    ellipsoid per grid point of status 0 at the output's position, one scale for all (the largest
    radius drawn ``size`` m; default half the median distance between neighbouring positions, or
    5 % of the robot's size), coloured by the worst compliance. Returns the colour range (m/N).

    Raises:
        ParameterError: not a motor-space atlas, no point of status 0, over :data:`MAX_ELLIPSOIDS`.
    """
    pos, radii, axes, worst = field_points(ds)
    if len(pos) == 0:
        raise ParameterError("atlas: no grid point of status 0 (assembled and restrained) to draw")
    if len(pos) > MAX_ELLIPSOIDS:
        raise ParameterError(f"atlas: {len(pos):,} ellipsoids, over {MAX_ELLIPSOIDS:,}; draw a coarser atlas")
    if size is None:  # half the median distance to the nearest other point, or 5 % of the robot
        gaps = np.linalg.norm(pos[:, None] - pos[None], axis=-1) if 1 < len(pos) <= 1000 else np.zeros((1, 1))
        np.fill_diagonal(gaps, np.inf)
        near = gaps.min(axis=1)
        near = near[np.isfinite(near) & (near > 1e-9)]
        size = float(np.median(near) / 2) if near.size else 0.05 * _extent(scene)
    if not (np.isfinite(size) and size > 0):
        raise ParameterError(f"size: a finite radius > 0 (m), got {size!r}")
    lo, hi = float(worst.min()), float(worst.max())
    scale = size / hi
    cmap = matplotlib.colormaps["viridis"]
    for n in range(len(pos)):
        colour = hex_color(cmap((worst[n] - lo) / (hi - lo) if hi > lo else 0.5))
        scene._draw_ellipsoid(f"{path}/{n}", pos[n], np.maximum(radii[n], 0) * scale, axes[n], colour, 0.85)
    scene.legend.append(f"field: {len(pos)} of {ds.status.size} grid points of the atlas, worst compliance "
                        f"{lo * 1e6:.3g} (dark) to {hi * 1e6:.3g} (yellow) um/N, radius {size * 1e3:.3g} mm for "
                        f"{hi * 1e6:.3g} um/N")
    return lo, hi


def _extent(scene: MechanismScene) -> float:
    mech = scene.mechanism
    d = mech.model.createData()
    pin.forwardKinematics(mech.model, d, scene.q)
    pts = np.array([d.oMi[j].translation for j in range(mech.model.njoints)])
    return max(float(np.ptp(pts, axis=0).max()), 1e-3)


def draw_load(scene: MechanismScene, springs: Mapping[str, Any], output: str, load: Any, locked: Iterable[Any] = (),
              exaggeration: float | None = None) -> float:
    """The deflected robot under ``load`` at ``output`` (:func:`joint_deflection`) as a red
    ghost, exaggerated (default: the output moves about 30 mm, or a tenth of the robot's size if
    smaller), and an arrow for the force. Returns the exaggeration."""
    mech, q = scene.mechanism, scene.q
    dq, dy = joint_deflection(mech, q, springs, output, load, locked)
    w = _wrench(load)
    moved = float(np.linalg.norm(dy[:3]))
    if exaggeration is None:
        exaggeration = nice(min(GHOST_SIZE, 0.1 * _extent(scene)) / max(moved, 1e-15))
    draw_mechanism(scene.vis, mech, pin.integrate(mech.model, q, exaggeration * dq), "ghost",
                   (0xe04040,) * 4, 0.4)
    d = mech.model.createData()
    pin.framesForwardKinematics(mech.model, d, q)
    at = d.oMf[mech.model.getFrameId(output)].translation
    if np.linalg.norm(w[:3]) > 0:
        scene._arrow("load", at - w[:3] / np.linalg.norm(w[:3]) * 0.12, w[:3])
    scene.legend.append(f"red ghost: deflection under F = ({', '.join(f'{f:g}' for f in w[:3])}) N at {output}, "
                        f"exaggerated x{exaggeration:g} (true |d{output}| = {moved * 1e6:.3g} um)")
    return exaggeration


def show(mech: Any, q: Any = None, springs: Mapping[str, Any] | None = None, output: str | None = None,
         locked: Iterable[Any] = (), *, atlas: Any = None, load: Any = None, scale: float | None = None,
         size: float | None = None, exaggeration: float | None = None,
         host: str = meshcat_server.LOCALHOST) -> MechanismScene:
    """Any closed-loop robot in a new meshcat server: its stick drawing at ``q`` (default the
    reference assembly), the compliance ellipsoid at ``output`` (``scale`` mm per um/N), the
    ellipsoid field of ``atlas`` (:func:`draw_field`, ``size``) and the deflected shape under
    ``load`` (:func:`draw_load`, ``exaggeration``). ``springs``, ``output`` and ``locked``
    default to the atlas's (its attributes). ``html()``/``write_html(path)``: a self-contained
    page; ``close()`` stops the server.

    Raises:
        ParameterError: no output frame, a load without springs, a bad load; as
            :meth:`h4pin.elastic.Mechanism.compliance` (before any server starts).
    """
    if atlas is not None:
        field_points(atlas)
        springs = json.loads(atlas.attrs["springs"]) if springs is None else springs
        output = atlas.attrs["output"] if output is None else output
        locked = tuple(locked) or tuple(json.loads(atlas.attrs.get("locked", "[]")))
    if load is not None:
        _wrench(load)
        if springs is None or output is None:
            raise ParameterError("load: give the springs and the output frame (or an atlas that holds them)")
    q = mech.assemble() if q is None else q
    scene = MechanismScene(mech, q, springs, output, locked, scale=scale, host=host)
    try:
        if atlas is not None:
            draw_field(scene, atlas, size)
        if load is not None:
            draw_load(scene, springs, output, load, locked, exaggeration)
    except BaseException:
        scene.close()
        raise
    return scene
