# SPDX-License-Identifier: Apache-2.0
"""The H4 in a browser: meshcat scene with compliance ellipsoids and the deflected robot.

The viewer only draws: it asks :mod:`h4pin.stiffness.api` and :mod:`h4pin.stiffness.deflection` for numbers.

    from h4pin import load

    from h4pin.io import viewer
    scene = viewer.show(load(), load=[0, 0, -10], field=True)   # starts a meshcat server
    print(scene.url)                                             # open it in a browser
    scene.write_html("h4.html")                                  # self-contained page (offline)
    scene.close()                                                # stops the server

What is drawn, and the scales (also written in the page's legend, :attr:`Scene.legend`):

* the robot at the pose, from the URDF's visual geometry;
* the translational compliance ellipsoid at D: its axes are the eigenvectors of the symmetric
  part of the 3x3 block, its radii the eigenvalues (deflection under a unit force along that
  axis) times ``scale`` (mm drawn per um/N); optionally the rotational one (rad/(N.m) block);
* under a load: a transparent ghost of the deflected robot, exaggerated ``exaggeration`` times,
  and an arrow for the force at D;
* optionally an ellipsoid field over a workspace grid, coloured by the largest translational
  compliance (um/N, viridis; the range is in the legend);
* optionally a natural mode of the elastic robot (:func:`h4pin.modes`), animated and exaggerated
  (:meth:`Scene.mode`; the static page keeps the animation).
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import Any

import matplotlib
import meshcat
import meshcat.geometry as mg
import meshcat.transformations as mt
import numpy as np
import pinocchio as pin
from pinocchio.visualize import MeshcatVisualizer
from tqdm import tqdm

from h4pin import limits
from h4pin.errors import ParameterError
from h4pin.files import write_text
from h4pin.io import meshcat_server
from h4pin.kinematics import closed_form as geometry
from h4pin.kinematics.closed_form import centre_pose
from h4pin.robot import H4
from h4pin.stiffness.api import as_load, compliance
from h4pin.stiffness.deflection import deflected_configuration, deflection

ELLIPSOID_SIZE = 0.12  # m: default drawn radius of the largest ellipsoid axis (at most)
GHOST_SIZE = 0.03  # m: default drawn deflection of D
ARROW_LENGTH = 0.12  # m


def ellipsoid_axes(block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Radii (3,) and axes (3, 3), columns, of the compliance ellipsoid of a 3x3 block.

    The eigen-decomposition of the symmetric part: along axis k a unit force deflects by
    ``radii[k]`` (the block's unit per N). Axes form a right-handed frame.
    """
    vals, vecs = np.linalg.eigh((block + block.T) / 2)
    if np.linalg.det(vecs) < 0:
        vecs[:, 0] = -vecs[:, 0]
    return vals, vecs


def draw_ellipsoid(vis: meshcat.Visualizer, path: str, block: np.ndarray, centre: np.ndarray,
                   scale: float | None = None, colour: int = 0x20b050, opacity: float = 0.6) -> float:
    """Draw the compliance ellipsoid of a 3x3 block (m/N) at ``centre`` (m), for any robot and frame.

    Axes and radii from :func:`ellipsoid_axes`; ``scale``: mm drawn per um/N (default: the largest
    radius drawn about 120 mm). Returns the scale used. E.g. a serial arm's tool frame, with
    :func:`h4pin.studies.serial.serial_compliance`'s ``translational`` block and ``position``.
    """
    radii, axes = ellipsoid_axes(np.asarray(block, float))
    um = radii * 1e6
    if scale is None:
        scale = nice(ELLIPSOID_SIZE * 1e3 / um.max())
    vis[path].set_object(mg.Ellipsoid(np.maximum(um * scale * 1e-3, 1e-5)),
                         mg.MeshLambertMaterial(color=colour, opacity=opacity, transparent=True))
    vis[path].set_transform(_transform(axes, np.asarray(centre, float)))
    return scale


def nice(x: float) -> float:
    """The largest of 1, 2, 5 x 10^n not above x."""
    exp = np.floor(np.log10(x))
    return float(max(m for m in (1.0, 2.0, 5.0) if m * 10**exp <= x * (1 + 1e-12)) * 10**exp)


def _transform(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    tf = np.eye(4)
    tf[:3, :3] = rotation
    tf[:3, 3] = translation
    return tf


def _rotation_y_to(d: np.ndarray) -> np.ndarray:
    """A rotation taking +y (meshcat's cylinder axis) to the unit vector d."""
    d = d / np.linalg.norm(d)
    y = np.array([0.0, 1.0, 0.0])
    axis = np.cross(y, d)
    s, c = np.linalg.norm(axis), float(y @ d)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return pin.exp3(axis / s * np.arctan2(s, c))


def hex_color(rgb: np.ndarray) -> int:
    r, g, b = (int(round(255 * c)) for c in rgb[:3])
    return (r << 16) + (g << 8) + b


class Scene:
    """A meshcat scene showing one H4. Owns the meshcat server it starts (see :meth:`close`).

    Args:
        h4: The robot.
        vis: An existing ``meshcat.Visualizer`` to draw into (then :meth:`close` leaves its
            server alone). Default: start a new server (:mod:`h4pin.io.meshcat_server`), quietly.
        host: Interface the new server's web page listens on: ``"127.0.0.1"`` (default, this
            machine only), or e.g. ``"0.0.0.0"`` to let other machines connect. The server's
            command socket stays on 127.0.0.1. Ignored with ``vis``.
    """

    def __init__(self, h4: H4, vis: meshcat.Visualizer | None = None, host: str = meshcat_server.LOCALHOST):
        self.h4 = h4
        self._server = None
        self.legend: list[str] = []
        try:
            vis = self._connect(vis, host)
            self.robot = MeshcatVisualizer(h4.model, h4.collision_model, h4.visual_model)
            self.robot.initViewer(viewer=vis)
            self.robot.loadViewerModel(rootNodeName="h4")
            self.robot.displayCollisions(False)
            self.robot.displayVisuals(True)
            vis["/Grid"].set_property("visible", False)
            vis["/Axes"].set_property("visible", False)
            # The camera orbits the scene origin: lift the drawing so the robot's middle sits there.
            self.vis.set_transform(mt.translation_matrix([0.0, 0.0, 0.33]))
            self.look_at(np.array([0.3, -0.78, 0.12]))
        except BaseException:
            self.close()
            raise

    def _connect(self, vis: meshcat.Visualizer | None, host: str) -> meshcat.Visualizer:
        """``vis``, or a new meshcat server of this scene's own (quietly) and its visualizer."""
        if vis is None:
            self._server, zmq_url, _ = meshcat_server.start(host)
            with contextlib.redirect_stdout(io.StringIO()):
                vis = meshcat.Visualizer(zmq_url=zmq_url)
        self.vis = vis
        return vis

    @property
    def url(self) -> str:
        """Address of the meshcat page."""
        return self.vis.url()

    def look_at(self, offset: np.ndarray) -> None:
        """Camera at ``offset`` (m, z up) from the middle of the robot (0.33 m below the
        actuators), looking at it."""
        # three.js camera coordinates are y-up: (x, y, z)_world -> (x, z, -y)
        self.vis["/Cameras/default/rotated/<object>"].set_property(
            "position", [float(offset[0]), float(offset[2]), float(-offset[1])])

    def pose(self, pose: np.ndarray) -> np.ndarray:
        """Draw the robot at ``pose`` [x, y, z, theta] (m, rad); returns its configuration."""
        q = self.h4.configuration(pose)
        self.robot.display(q)
        return q

    def ellipsoid(self, pose: np.ndarray, model: str = "consistent", scale: float | None = None,
                  rotational: bool = False) -> float:
        """Draw the translational (and optionally rotational) compliance ellipsoid at D.

        Args:
            scale: mm drawn per um/N; default: the largest radius is drawn about 60 mm.

        Returns:
            The scale used (mm per um/N).
        """
        x = geometry.as_poses(pose)
        if scale is not None:
            limits.check_range("scale", scale, "scale")
        k = compliance(self.h4, x, model).matrix
        radii, axes = ellipsoid_axes(k[:3, :3])
        um = radii * 1e6
        if scale is None:
            scale = nice(ELLIPSOID_SIZE * 1e3 / um.max())
        self._draw_ellipsoid("compliance/translational", x[:3], um * scale * 1e-3, axes, 0x20b050, 0.6)
        self.legend.append(f"green: translational compliance ellipsoid at D, 1 um/N drawn as {scale:g} mm "
                           f"(radii {', '.join(f'{v:.1f}' for v in um)} um/N, model '{model}')")
        if rotational:
            rr, ra = ellipsoid_axes(k[3:6, 3:6])
            rscale = ELLIPSOID_SIZE / rr.max()
            self._draw_ellipsoid("compliance/rotational", x[:3], rr * rscale, ra, 0xe040e0, 0.35)
            self.legend.append(f"magenta: rotational ellipsoid, 1 urad/(N.m) drawn as {rscale * 1e-3:.3g} mm "
                               f"(radii {', '.join(f'{v * 1e6:.1f}' for v in rr)} urad/(N.m))")
        return scale

    def _draw_ellipsoid(self, path: str, centre: np.ndarray, radii: np.ndarray, axes: np.ndarray,
                        colour: int, opacity: float) -> None:
        self.vis[path].set_object(mg.Ellipsoid(np.maximum(radii, 1e-5)),
                                  mg.MeshLambertMaterial(color=colour, opacity=opacity, transparent=True))
        self.vis[path].set_transform(_transform(axes, centre))

    def load(self, pose: np.ndarray, load: np.ndarray, model: str = "consistent",
             exaggeration: float | None = None) -> float:
        """Draw the ghost of the deflected robot under ``load`` and an arrow for the force.

        Args:
            load: Force F (3,) in N at D, or Gamma_ext (8,).
            exaggeration: Factor on the deflection; default: D moves about 30 mm on screen.

        Returns:
            The exaggeration used.
        """
        x = geometry.as_poses(pose)
        g = as_load(load)
        if exaggeration is not None:
            limits.check_range("exaggeration", exaggeration, "exaggeration")
        dtp, _ = deflection(self.h4, x, g, model)
        if exaggeration is None:
            exaggeration = nice(GHOST_SIZE / max(np.linalg.norm(dtp[:3]), 1e-12))
        q = deflected_configuration(self.h4, x, g, scale=exaggeration, model=model)
        ghost = MeshcatVisualizer(self.h4.model, self.h4.collision_model, self.h4.visual_model)
        ghost.initViewer(viewer=self.vis)
        ghost.loadViewerModel(rootNodeName="ghost", visual_color=[0.9, 0.25, 0.2, 0.35])
        ghost.displayCollisions(False)
        ghost.display(q)
        force = g[:3]
        if np.linalg.norm(force) > 0:
            self._arrow("load", x[:3] - force / np.linalg.norm(force) * ARROW_LENGTH, force)
        self.legend.append(f"red ghost: deflection under F = ({', '.join(f'{f:g}' for f in force)}) N "
                           f"exaggerated x{exaggeration:g} (true |dD| = {np.linalg.norm(dtp[:3]) * 1e6:.1f} um)")
        return exaggeration

    def mode(self, pose: np.ndarray, index: int = 0, payload=None, amplitude: float | None = None,
             frames: int = 48, robot=None) -> tuple[float, float]:
        """Animate natural mode ``index`` (0: the first) of the elastic robot at ``pose``
        (:func:`h4pin.modes`), exaggerated, as a meshcat animation (kept by :meth:`html`).

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
        from meshcat.animation import Animation

        from h4pin.elastic import elastic_model, modes
        from h4pin.errors import ParameterError
        from h4pin.kinematics import pinocchio as kin
        from h4pin.kinematics.closed_form import PlateState

        x = geometry.as_pose(pose)
        em = robot if robot is not None else elastic_model(self.h4)
        res = modes(em, x, payload)
        if not (isinstance(index, int | np.integer) and 0 <= index < len(res.frequencies)):
            raise ParameterError(f"mode index must be an integer in 0..{len(res.frequencies) - 1}, got {index!r}")
        tp = res.shapes_tp[index]
        act = np.array([res.shapes_q[index, em.model.joints[em.model.getJointId(f"actuator_{i + 1}_elastic")].idx_v]
                        for i in range(4)])
        if amplitude is None:
            amplitude = nice(GHOST_SIZE / max(np.linalg.norm(tp[:3]), 1e-12))
        st = kin.state(self.h4, x)
        anim = Animation(default_framerate=24)
        viewer, self.robot.viewer = self.robot.viewer, None
        try:
            for f in range(frames):
                a = amplitude * np.sin(2 * np.pi * f / frames)
                q = kin.assemble(self.h4, PlateState(st.q + a * act, st.D + a * tp[:3], pin.exp3(a * tp[3:6]) @ st.R,
                                                     st.omega + a * tp[6:8]))
                with anim.at_frame(self.vis, f) as frame:
                    self.robot.viewer = frame
                    self.robot.display(q)
        finally:
            self.robot.viewer = viewer
        self.vis.set_animation(anim, play=True, repetitions=0)
        freq = float(res.frequencies[index])
        self.legend.append(f"animation: mode {index + 1} of the elastic robot, {freq:.1f} Hz"
                           f"{'' if payload is None else f' with a {payload.mass:g} kg payload'}, exaggerated "
                           f"x{amplitude:g} (mass-normalised shape; actuators locked)")
        return freq, amplitude

    def _arrow(self, path: str, start: np.ndarray, direction: np.ndarray) -> None:
        rot = _rotation_y_to(direction)
        shaft, head = 0.8 * ARROW_LENGTH, 0.2 * ARROW_LENGTH
        material = mg.MeshLambertMaterial(color=0xd02020)
        self.vis[f"{path}/shaft"].set_object(mg.Cylinder(shaft, 0.004), material)
        self.vis[f"{path}/shaft"].set_transform(_transform(rot, start + rot @ [0, shaft / 2, 0]))
        self.vis[f"{path}/head"].set_object(mg.Cylinder(head, radiusTop=0.0, radiusBottom=0.012), material)
        self.vis[f"{path}/head"].set_transform(_transform(rot, start + rot @ [0, shaft + head / 2, 0]))

    def field(self, poses: np.ndarray, model: str = "consistent", size: float = 0.025,
              progress: bool = True) -> tuple[float, float]:
        """Ellipsoids at many poses, coloured by the largest translational compliance.

        Unreachable or singular poses are skipped. Every ellipsoid uses one scale so that the
        largest is drawn with radius ``size`` (m).

        Returns:
            The colour range (um/N) of the largest eigenvalue.
        """
        x = geometry.as_poses(poses)
        x = x[None] if x.ndim == 1 else x
        res = compliance(self.h4, x, model, on_error="nan")
        ok = np.flatnonzero(res.valid)
        if ok.size == 0:
            raise ValueError("no pose of the field is reachable and regular")
        blocks = [ellipsoid_axes(res.matrix[n, :3, :3]) for n in ok]
        top = np.array([r.max() for r, _ in blocks]) * 1e6
        lo, hi = float(top.min()), float(top.max())
        scale = size / (hi * 1e-6)
        cmap = matplotlib.colormaps["viridis"]
        for n, (radii, axes), t in tqdm(list(zip(ok, blocks, top, strict=True)), desc="ellipsoid field",
                                        unit="pose", disable=not progress):
            colour = hex_color(cmap((t - lo) / (hi - lo) if hi > lo else 0.5))
            self._draw_ellipsoid(f"field/{n}", x[n, :3], radii * scale, axes, colour, 0.85)
        self.legend.append(f"field: {ok.size} of {len(x)} poses, largest compliance {lo:.1f} (dark) to "
                           f"{hi:.1f} (yellow) um/N, radius {size * 1e3:g} mm for {hi:.1f} um/N")
        return lo, hi

    def html(self) -> str:
        """A self-contained HTML page of the scene (meshcat's static HTML, works offline), with
        the legend written in a corner."""
        page = self.vis.static_html()
        if not self.legend:
            return page
        items = "".join(f"<div>{line}</div>" for line in self.legend)
        box = ('<div id="h4pin-legend" style="position:absolute;left:8px;bottom:8px;padding:6px 10px;'
               'background:rgba(255,255,255,0.85);font:13px sans-serif;color:#222;z-index:10">'
               f"<b>h4pin</b>{items}</div>")
        return page.replace("</body>", box + "</body>", 1)

    def write_html(self, path: str | Path) -> Path:
        """Write :meth:`html` to ``path`` atomically (no partial file if anything fails)."""
        return write_text(path, self.html())

    def close(self) -> None:
        """Stop the meshcat server this scene started (``Visualizer.close`` does not); idempotent."""
        server, self._server = self._server, None
        if server is None:
            return
        vis = getattr(self, "vis", None)
        if vis is not None:
            vis.window.zmq_socket.close(linger=0)
        meshcat_server.stop(server)

    @property
    def server_pid(self) -> int | None:
        """Process id of the meshcat server this scene owns (``None`` once closed or with ``vis``)."""
        return None if self._server is None else self._server.pid

    def __enter__(self) -> Scene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class MechanismScene(Scene):
    """A meshcat scene of any closed-loop robot (:class:`h4pin.elastic.Mechanism`) at a
    configuration: a stick drawing (each joint a ball, each link a rod from its parent joint,
    each closure's two points), and the compliance ellipsoid of an output frame. Owns its
    meshcat server as :class:`Scene` (``close``, ``html``, ``write_html``, ``url``).

    Args:
        mechanism: the robot; q: an assembled configuration (nq,).
        springs, locked, output: as :meth:`h4pin.elastic.Mechanism.compliance`, for the
            ellipsoid of the frame ``output`` (none drawn when ``springs`` or ``output`` is None).
        scale: mm drawn per um/N (default: the largest radius about 120 mm).
        vis, host: as :class:`Scene`.

    Raises:
        as :meth:`h4pin.elastic.Mechanism.compliance` (before any server starts).
    """

    def __init__(self, mechanism: Any, q: Any, springs: Any = None, output: str | None = None, locked: Any = (), *,
                 scale: float | None = None, vis: meshcat.Visualizer | None = None,
                 host: str = meshcat_server.LOCALHOST):
        from h4pin.elastic.engine import frame_id
        from h4pin.elastic.mechanism import Mechanism

        if not isinstance(mechanism, Mechanism):
            raise ParameterError(f"mechanism: an h4pin.elastic.Mechanism, got {type(mechanism).__name__}")
        q = mechanism._q(q)
        block = None
        if springs is not None and output is not None:
            block = mechanism.compliance(q, springs, [output], locked)[:3, :3]
        model, d = mechanism.model, mechanism.model.createData()
        pin.framesForwardKinematics(model, d, q)
        self.h4 = None
        self.mechanism, self.q = mechanism, q
        self._server = None
        self.legend = [f"{mechanism.name}: {model.njoints - 1} joints, {len(mechanism.constraint_models)} closures"]
        try:
            vis = self._connect(vis, host)
            vis["/Grid"].set_property("visible", False)
            vis["/Axes"].set_property("visible", False)
            draw_mechanism(vis, mechanism, q)
            # The camera orbits the scene origin: move the robot's middle there, look from its size.
            pin.forwardKinematics(model, d, q)
            points = np.array([d.oMi[j].translation for j in range(model.njoints)])
            vis.set_transform(mt.translation_matrix(-0.5 * (points.min(axis=0) + points.max(axis=0))))
            self.look_at(np.array([1.2, -1.2, 0.9]) * max(float(np.ptp(points, axis=0).max()), 1e-3))
            if block is not None:
                centre = d.oMf[frame_id(model, output)].translation
                used = draw_ellipsoid(vis, "mechanism/ellipsoid", block, centre, scale)
                radii, _ = ellipsoid_axes(block)
                self.legend.append(f"compliance ellipsoid at {output}: {used:g} mm per um/N, largest "
                                   f"{radii.max() * 1e6:.3g} um/N")
        except BaseException:
            self.close()
            raise


def draw_mechanism(vis: meshcat.Visualizer, mechanism: Any, q: np.ndarray, path: str = "mechanism",
                   colours: tuple[int, int, int, int] = (0xd0a020, 0x606060, 0x3060c0, 0xd02020),
                   opacity: float = 1.0) -> None:
    """A stick drawing of a :class:`h4pin.elastic.Mechanism` at q (nq,) under ``path``: each
    joint a ball (``joints/<name>``; motors in the first colour, the others in the second), each
    link a rod from its parent joint (``links/<name>``, third colour), each closure's two points
    (``closures/<name>/1`` and ``2``, fourth colour). Sizes from the robot's extent at q."""
    model, d = mechanism.model, mechanism.model.createData()
    pin.forwardKinematics(model, d, q)
    points = np.array([d.oMi[j].translation for j in range(model.njoints)])
    size = max(float(np.ptp(points, axis=0).max()), 1e-3)
    rod, ball = 0.01 * size, 0.025 * size

    def material(colour: int) -> mg.MeshLambertMaterial:
        return mg.MeshLambertMaterial(color=colour, opacity=opacity, transparent=opacity < 1)

    for j in range(1, model.njoints):
        a, b = points[model.parents[j]], points[j]
        name = model.names[j]
        vis[f"{path}/joints/{name}"].set_object(mg.Sphere(ball), material(colours[0 if name in mechanism.actuated
                                                                                   else 1]))
        vis[f"{path}/joints/{name}"].set_transform(mt.translation_matrix(b))
        if np.linalg.norm(b - a) > 1e-9:
            vis[f"{path}/links/{name}"].set_object(mg.Cylinder(float(np.linalg.norm(b - a)), rod), material(colours[2]))
            vis[f"{path}/links/{name}"].set_transform(_transform(_rotation_y_to(b - a), 0.5 * (a + b)))
    for cm in mechanism.constraint_models:
        for side, (jid, place) in enumerate(((cm.joint1_id, cm.joint1_placement), (cm.joint2_id, cm.joint2_placement))):
            vis[f"{path}/closures/{cm.name}/{side + 1}"].set_object(mg.Sphere(0.6 * ball), material(colours[3]))
            vis[f"{path}/closures/{cm.name}/{side + 1}"].set_transform(mt.translation_matrix((d.oMi[jid] * place)
                                                                                             .translation))


def show_mechanism(mechanism: Any, q: Any, springs: Any = None, output: str | None = None, locked: Any = (), *,
                   scale: float | None = None, host: str = meshcat_server.LOCALHOST) -> MechanismScene:
    """:class:`MechanismScene` of any closed-loop robot, in a new meshcat server (``html()`` or
    ``write_html(path)`` for a self-contained page; ``close()`` stops the server)."""
    return MechanismScene(mechanism, q, springs, output, locked, scale=scale, host=host)


def workspace_grid(h4: H4, n: int = 5, span: float = 0.2, heights: tuple[float, ...] = (-0.05, 0.05)) -> np.ndarray:
    """Poses (theta = 0) on an n x n grid of side ``span`` (m) around the centre, at the centre's
    height plus each of ``heights`` (m)."""
    c = centre_pose(h4)
    xs = np.linspace(-span / 2, span / 2, n)
    return np.array([[c[0] + a, c[1] + b, c[2] + dz, 0.0] for dz in heights for a in xs for b in xs])


def show(h4: H4, pose: np.ndarray | None = None, load: np.ndarray | None = None, *, scale: float | None = None,
         exaggeration: float | None = None, field: bool = False, rotational: bool = False,
         model: str = "consistent", vis: meshcat.Visualizer | None = None,
         host: str = meshcat_server.LOCALHOST, mode: int | None = None, payload=None) -> Scene:
    """Draw the H4 at ``pose`` with its compliance ellipsoid, and optionally more.

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
        mode: Also animate this natural mode of the elastic robot (0: the first; :meth:`Scene.mode`).
        payload: An :class:`h4pin.Payload` on the plate for ``mode``.

    Returns:
        The :class:`Scene` (``scene.url``, ``scene.write_html(path)``, ``scene.close()``).

    Raises:
        UnreachablePoseError, SingularPoseError: as :func:`h4pin.compliance`; no server is left.
    """
    x = centre_pose(h4) if pose is None else geometry.as_poses(pose)
    if x.ndim != 1:
        raise ValueError(f"show takes one pose (4,), got shape {x.shape}")
    compliance(h4, x, model)  # fail before starting a server
    if load is not None:
        as_load(load)
    for name, value in (("scale", scale), ("exaggeration", exaggeration)):
        if value is not None:
            limits.check_range(name, value, name)
    scene = Scene(h4, vis, host)
    try:
        scene.pose(x)
        scene.ellipsoid(x, model, scale, rotational)
        if load is not None:
            scene.load(x, load, model, exaggeration)
        if field:
            scene.field(workspace_grid(h4), model)
        if mode is not None:
            scene.mode(x, mode, payload)
    except BaseException:
        scene.close()
        raise
    return scene


def screenshot(html: str | Path, png: str | Path, size: tuple[int, int] = (1000, 750),
               browser: str | None = None, timeout: float = 120.0) -> Path:
    """Render a page (e.g. from :meth:`Scene.write_html`) to a PNG with headless Chromium.

    Uses Debian's ``chromium`` (software WebGL), a fresh profile, and no network.

    Raises:
        FileNotFoundError: no Chromium on the PATH.
        RuntimeError: Chromium did not write the screenshot.
    """
    exe = browser or shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        raise FileNotFoundError("headless rendering needs Chromium (Debian: apt-get install chromium)")
    png = Path(png).resolve()
    with tempfile.TemporaryDirectory(prefix="h4pin-chromium-") as profile:
        args = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-quic",
                "--no-first-run", "--disable-background-networking", "--disable-component-update", "--disable-sync",
                f"--user-data-dir={profile}", "--virtual-time-budget=8000", f"--window-size={size[0]},{size[1]}",
                f"--screenshot={png}", Path(html).resolve().as_uri()]
        subprocess.run(args, capture_output=True, timeout=timeout, check=False)
    if not png.is_file():
        raise RuntimeError(f"Chromium did not write {png}")
    os.chmod(png, 0o644)  # like any file h4pin writes, whatever Chromium's umask
    return png
