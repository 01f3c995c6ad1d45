# SPDX-License-Identifier: Apache-2.0
"""Any robot in a browser: the one meshcat scene of h4pin (:class:`Scene`), and what it draws of a
:class:`~h4pin.mechanism.Mechanism` (:func:`show`).

A scene draws; it computes nothing of a robot's stiffness. Its caller passes the numbers (a
compliance block and where it acts, a deflected configuration, an atlas's field), so that each
is computed once. What it needs of the robot it draws (its *subject*) is small:

* ``model`` (a ``pin.Model``) and ``configuration(at)`` (a configuration from what the caller
  holds: a configuration for a mechanism, a pose for the H4);
* optionally ``visual_model`` and ``collision_model`` (``pin.GeometryModel``): the robot is then
  drawn with its meshes (Pinocchio's ``MeshcatVisualizer``), else as sticks: each joint a ball
  (the ``actuated`` ones yellow), each link a rod from its parent joint, each closure's two points
  (``constraint_models``) red.

The H4's viewer (:mod:`h4pin.io.viewer`) and :func:`show` here are its two clients::

    from h4pin.mechanism import Mechanism, scene

    delta = Mechanism.from_urdf("tests/robots/robot_delta/robot.urdf")
    with scene.show(delta, springs={m: 100.0 for m in delta.actuated}, output="eff",
                    load=[0, -10, 0]) as s:
        s.write_html("delta.html")

:func:`show` draws, and states in the page's legend: the robot at q; the compliance ellipsoid of
an output frame (radii the eigenvalues of the symmetric part of C_tt, axes its eigenvectors); a
motor-space atlas's ellipsoid field (:mod:`h4pin.mechanism.atlas`, read as stored); under a load
(force (3,) N or wrench (6,) N, N.m at the output's origin, world axes) the deflected robot as a
red ghost, exaggerated, and an arrow for the force. The joint deflections are ``dq = C_qw w``
(:func:`joint_deflection`), from the same compliance as the ellipsoid.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib
import meshcat
import meshcat.geometry as mg
import meshcat.transformations as mt
import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.files import write_text
from h4pin.mechanism import meshcat_server

ELLIPSOID_SIZE = 0.12  # m: default drawn radius of the largest ellipsoid axis (at most)
GHOST_SIZE = 0.03  # m: default drawn deflection of the output
ARROW_LENGTH = 0.12  # m
#: At most this many ellipsoids are drawn in a field (a page of a few MB).
MAX_ELLIPSOIDS = 5000
#: Colours of the stick drawing: motor joints, other joints, links, closure points.
STICK_COLOURS = (0xd0a020, 0x606060, 0x3060c0, 0xd02020)


def ellipsoid_axes(block: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Radii (3,) and axes (3, 3), columns, of the compliance ellipsoid of a 3x3 block.

    The eigen-decomposition of the symmetric part: along axis k a unit force deflects by
    ``radii[k]`` (the block's unit per N). Axes form a right-handed frame.
    """
    vals, vecs = np.linalg.eigh((block + block.T) / 2)
    if np.linalg.det(vecs) < 0:
        vecs[:, 0] = -vecs[:, 0]
    return vals, vecs


def nice(x: float) -> float:
    """The largest of 1, 2, 5 x 10^n not above x."""
    exp = np.floor(np.log10(x))
    return float(max(m for m in (1.0, 2.0, 5.0) if m * 10**exp <= x * (1 + 1e-12)) * 10**exp)


def hex_color(rgb: Sequence[float]) -> int:
    r, g, b = (int(round(255 * c)) for c in rgb[:3])
    return (r << 16) + (g << 8) + b


def transform(rotation: np.ndarray, translation: np.ndarray) -> np.ndarray:
    """The 4x4 homogeneous transform of a rotation and a translation."""
    tf = np.eye(4)
    tf[:3, :3] = rotation
    tf[:3, 3] = translation
    return tf


def rotation_y_to(d: np.ndarray) -> np.ndarray:
    """A rotation taking +y (meshcat's cylinder axis) to the unit vector d."""
    d = d / np.linalg.norm(d)
    y = np.array([0.0, 1.0, 0.0])
    axis = np.cross(y, d)
    s, c = np.linalg.norm(axis), float(y @ d)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return pin.exp3(axis / s * np.arctan2(s, c))


def draw_ellipsoid(vis: meshcat.Visualizer, path: str, block: np.ndarray, centre: np.ndarray,
                   scale: float | None = None, colour: int = 0x20b050, opacity: float = 0.6) -> float:
    """Draw the compliance ellipsoid of a 3x3 block (m/N) at ``centre`` (m), into any meshcat
    visualizer: axes and radii from :func:`ellipsoid_axes`; ``scale``: mm drawn per um/N (default:
    the largest radius drawn about 120 mm). Returns the scale used. E.g. a serial arm's tool frame,
    with :func:`h4pin.studies.serial.serial_compliance`'s ``translational`` block and ``position``."""
    radii, axes = ellipsoid_axes(np.asarray(block, float))
    um = radii * 1e6
    if scale is None:
        scale = nice(ELLIPSOID_SIZE * 1e3 / um.max())
    vis[path].set_object(mg.Ellipsoid(np.maximum(um * scale * 1e-3, 1e-5)),
                         mg.MeshLambertMaterial(color=colour, opacity=opacity, transparent=True))
    vis[path].set_transform(transform(axes, np.asarray(centre, float)))
    return scale


def joint_points(model: pin.Model, q: np.ndarray) -> np.ndarray:
    """(njoints, 3): every joint's origin at q (the universe's first), world axes, m."""
    d = model.createData()
    pin.forwardKinematics(model, d, q)
    return np.array([d.oMi[j].translation for j in range(model.njoints)])


def extent(model: pin.Model, q: np.ndarray) -> float:
    """The robot's size at q: the largest side of the box around its joints (m, at least 1 mm)."""
    return max(float(np.ptp(joint_points(model, q), axis=0).max()), 1e-3)


def draw_sticks(vis: meshcat.Visualizer, subject: Any, q: np.ndarray, path: str = "mechanism",
                colours: tuple[int, int, int, int] = STICK_COLOURS, opacity: float = 1.0) -> None:
    """A stick drawing of ``subject`` (its ``model``, ``actuated`` joint names and
    ``constraint_models``) at q (nq,) under ``path``: each joint a ball (``joints/<name>``; motors
    in the first colour, the others in the second), each link a rod from its parent joint
    (``links/<name>``, third colour), each closure's two points (``closures/<name>/1`` and ``2``,
    fourth colour). Sizes from the robot's extent at q."""
    model = subject.model
    d = model.createData()
    pin.forwardKinematics(model, d, q)
    points = np.array([d.oMi[j].translation for j in range(model.njoints)])
    size = max(float(np.ptp(points, axis=0).max()), 1e-3)
    rod, ball = 0.01 * size, 0.025 * size
    motors = set(getattr(subject, "actuated", ()) or getattr(subject, "actuated_joint_names", ()))

    def material(colour: int) -> mg.MeshLambertMaterial:
        return mg.MeshLambertMaterial(color=colour, opacity=opacity, transparent=opacity < 1)

    for j in range(1, model.njoints):
        a, b = points[model.parents[j]], points[j]
        name = model.names[j]
        vis[f"{path}/joints/{name}"].set_object(mg.Sphere(ball), material(colours[0 if name in motors else 1]))
        vis[f"{path}/joints/{name}"].set_transform(mt.translation_matrix(b))
        if np.linalg.norm(b - a) > 1e-9:
            vis[f"{path}/links/{name}"].set_object(mg.Cylinder(float(np.linalg.norm(b - a)), rod), material(colours[2]))
            vis[f"{path}/links/{name}"].set_transform(transform(rotation_y_to(b - a), 0.5 * (a + b)))
    for cm in getattr(subject, "constraint_models", ()):
        for side, (jid, place) in enumerate(((cm.joint1_id, cm.joint1_placement), (cm.joint2_id, cm.joint2_placement))):
            vis[f"{path}/closures/{cm.name}/{side + 1}"].set_object(mg.Sphere(0.6 * ball), material(colours[3]))
            vis[f"{path}/closures/{cm.name}/{side + 1}"].set_transform(mt.translation_matrix((d.oMi[jid] * place)
                                                                                             .translation))


class Scene:
    """A meshcat scene of one robot (the module's *subject*: any :class:`Mechanism
    <h4pin.mechanism.Mechanism>`, or the H4). Owns the meshcat server it starts (:meth:`close`);
    draws what it is given (:meth:`draw`, :meth:`ellipsoid`, :meth:`ghost`, :meth:`arrow`,
    :meth:`field`, :meth:`animate`) and keeps a legend of it (:attr:`legend`, written in the page).

    Args:
        subject: what is drawn: ``model`` and ``configuration(at)``, optionally ``visual_model``
            and ``collision_model`` (meshes), ``actuated``, ``constraint_models`` (sticks).
        vis: an existing ``meshcat.Visualizer`` to draw into (then :meth:`close` leaves its
            server alone). Default: a new server (:mod:`h4pin.mechanism.meshcat_server`), quietly.
        host: interface the new server's web page listens on: ``"127.0.0.1"`` (default, this
            machine only), or e.g. ``"0.0.0.0"`` to let other machines connect. The server's
            command socket stays on 127.0.0.1. Ignored with ``vis``.
    """

    def __init__(self, subject: Any, vis: meshcat.Visualizer | None = None, host: str = meshcat_server.LOCALHOST):
        if not isinstance(getattr(subject, "model", None), pin.Model):
            raise ParameterError(f"subject: a robot with a pinocchio.Model (a Mechanism, an H4), got "
                                 f"{type(subject).__name__}")
        self.subject = subject
        self._server = None
        self._framed = False
        self.robot = None
        self.q: np.ndarray | None = None
        self.legend: list[str] = []
        try:
            vis = self._connect(vis, host)
            vis["/Grid"].set_property("visible", False)
            vis["/Axes"].set_property("visible", False)
            if getattr(subject, "visual_model", None) is not None:
                self.robot = self._visualizer("robot")
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

    def _visualizer(self, root: str, colour: list[float] | None = None) -> Any:
        from pinocchio.visualize import MeshcatVisualizer

        s = self.subject
        viz = MeshcatVisualizer(s.model, s.collision_model, s.visual_model)
        viz.initViewer(viewer=self.vis)
        viz.loadViewerModel(rootNodeName=root, **({} if colour is None else {"visual_color": colour}))
        viz.displayCollisions(False)
        viz.displayVisuals(True)
        return viz

    @property
    def url(self) -> str:
        """Address of the meshcat page."""
        return self.vis.url()

    def look_at(self, offset: np.ndarray) -> None:
        """Camera at ``offset`` (m, z up) from the scene's middle (:meth:`frame`), looking at it."""
        # three.js camera coordinates are y-up: (x, y, z)_world -> (x, z, -y)
        self.vis["/Cameras/default/rotated/<object>"].set_property(
            "position", [float(offset[0]), float(offset[2]), float(-offset[1])])

    def frame(self, centre: np.ndarray, eye: np.ndarray) -> None:
        """The drawing moved so that ``centre`` (m, world) is the point the camera orbits, and the
        camera at ``eye`` (m) from it."""
        self.vis.set_transform(mt.translation_matrix(-np.asarray(centre, float)))
        self.look_at(np.asarray(eye, float))
        self._framed = True

    def pose(self, at: Any) -> np.ndarray:
        """Draw the robot at ``subject.configuration(at)`` (a pose of the H4, a configuration of a
        mechanism); returns the configuration."""
        q = np.asarray(self.subject.configuration(at), float)
        self.draw(q)
        return q

    def draw(self, q: np.ndarray) -> None:
        """Draw the robot at configuration q (nq,) (meshes, or sticks under ``mechanism``); the
        first drawing frames the scene on the robot (:meth:`frame`) unless it was framed."""
        q = np.asarray(q, float)
        if self.robot is not None:
            self.robot.display(q)
        else:
            draw_sticks(self.vis, self.subject, q)
        self.q = q
        if not self._framed:
            pts = joint_points(self.subject.model, q)
            size = max(float(np.ptp(pts, axis=0).max()), 1e-3)
            self.frame(0.5 * (pts.min(axis=0) + pts.max(axis=0)), np.array([1.2, -1.2, 0.9]) * size)

    def ghost(self, q: np.ndarray, label: str | None = None) -> None:
        """The robot at q as a transparent red ghost (a deflected shape, exaggerated by the caller)."""
        if getattr(self.subject, "visual_model", None) is not None:
            self._visualizer("ghost", [0.9, 0.25, 0.2, 0.35]).display(np.asarray(q, float))
        else:
            draw_sticks(self.vis, self.subject, np.asarray(q, float), "ghost", (0xe04040,) * 4, 0.4)
        if label:
            self.legend.append(label)

    def ellipsoid(self, path: str, centre: np.ndarray, radii: np.ndarray, axes: np.ndarray,
                  colour: int = 0x20b050, opacity: float = 0.6) -> None:
        """An ellipsoid of ``radii`` (3,) m along the columns of ``axes`` (3, 3) at ``centre``."""
        self.vis[path].set_object(mg.Ellipsoid(np.maximum(radii, 1e-5)),
                                  mg.MeshLambertMaterial(color=colour, opacity=opacity, transparent=True))
        self.vis[path].set_transform(transform(axes, np.asarray(centre, float)))

    def compliance(self, block: np.ndarray, centre: np.ndarray, scale: float | None = None,
                   path: str = "compliance/translational", where: str = "the output") -> float:
        """The compliance ellipsoid of a 3x3 translational block (m/N) at ``centre`` (m), green:
        radii the eigenvalues of its symmetric part times ``scale`` (mm drawn per um/N; default
        the largest about 120 mm). Returns the scale; the legend states it."""
        radii, axes = ellipsoid_axes(np.asarray(block, float))
        um = radii * 1e6
        if scale is None:
            scale = nice(ELLIPSOID_SIZE * 1e3 / um.max())
        self.ellipsoid(path, centre, um * scale * 1e-3, axes)
        self.legend.append(f"green: translational compliance ellipsoid at {where}, 1 um/N drawn as {scale:g} mm "
                           f"(radii {', '.join(f'{v:.3g}' for v in um)} um/N)")
        return scale

    def arrow(self, path: str, start: np.ndarray, direction: np.ndarray) -> None:
        """A red arrow from ``start`` along ``direction`` (:data:`ARROW_LENGTH` long)."""
        rot = rotation_y_to(np.asarray(direction, float))
        shaft, head = 0.8 * ARROW_LENGTH, 0.2 * ARROW_LENGTH
        material = mg.MeshLambertMaterial(color=0xd02020)
        self.vis[f"{path}/shaft"].set_object(mg.Cylinder(shaft, 0.004), material)
        self.vis[f"{path}/shaft"].set_transform(transform(rot, start + rot @ [0, shaft / 2, 0]))
        self.vis[f"{path}/head"].set_object(mg.Cylinder(head, radiusTop=0.0, radiusBottom=0.012), material)
        self.vis[f"{path}/head"].set_transform(transform(rot, start + rot @ [0, shaft + head / 2, 0]))

    def force(self, at: np.ndarray, force: np.ndarray) -> None:
        """An arrow ending at ``at`` along ``force`` (nothing for a zero force)."""
        f = np.asarray(force, float)
        if np.linalg.norm(f) > 0:
            self.arrow("load", np.asarray(at, float) - f / np.linalg.norm(f) * ARROW_LENGTH, f)

    def field(self, positions: np.ndarray, radii: np.ndarray, axes: np.ndarray, worst: np.ndarray,
              size: float, path: str = "field") -> tuple[float, float]:
        """Ellipsoids at ``positions`` (n, 3) m of ``radii`` (n, 3) m/N along ``axes`` (n, 3, 3),
        one scale for all (the largest radius drawn ``size`` m), coloured by ``worst`` (n,) m/N
        (viridis). Returns the colour range (m/N).

        Raises:
            ParameterError: no point, over :data:`MAX_ELLIPSOIDS`, a bad ``size``.
        """
        if len(positions) == 0:
            raise ParameterError("field: no point to draw")
        if len(positions) > MAX_ELLIPSOIDS:
            raise ParameterError(f"field: {len(positions):,} ellipsoids, over {MAX_ELLIPSOIDS:,}; draw fewer")
        if not (np.isfinite(size) and size > 0):
            raise ParameterError(f"size: a finite radius > 0 (m), got {size!r}")
        lo, hi = float(np.min(worst)), float(np.max(worst))
        scale = size / hi
        cmap = matplotlib.colormaps["viridis"]
        for n in range(len(positions)):
            colour = hex_color(cmap((worst[n] - lo) / (hi - lo) if hi > lo else 0.5))
            self.ellipsoid(f"{path}/{n}", positions[n], np.maximum(radii[n], 0) * scale, axes[n], colour, 0.85)
        return lo, hi

    def animate(self, configurations: Iterable[np.ndarray], framerate: int = 24) -> int:
        """The robot through ``configurations`` as a looping meshcat animation (kept by
        :meth:`html`). Returns the number of frames."""
        from meshcat.animation import Animation

        anim = Animation(default_framerate=framerate)
        frames = 0
        if self.robot is not None:
            viewer, self.robot.viewer = self.robot.viewer, None
        try:
            for f, q in enumerate(configurations):
                with anim.at_frame(self.vis, f) as frame:
                    if self.robot is not None:
                        self.robot.viewer = frame
                        self.robot.display(np.asarray(q, float))
                    else:
                        draw_sticks(frame, self.subject, np.asarray(q, float))
                frames += 1
        finally:
            if self.robot is not None:
                self.robot.viewer = viewer
        self.vis.set_animation(anim, play=True, repetitions=0)
        return frames

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


def screenshot(html: str | Path, png: str | Path, size: tuple[int, int] = (1000, 750),
               browser: str | None = None, timeout: float = 120.0) -> Path:
    """Render a page (e.g. from :meth:`Scene.write_html`) to a PNG with headless Chromium: Debian's
    ``chromium`` (software WebGL), a fresh profile, no network.

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


# ------------------------------------------------------------------ a mechanism
def wrench(load: Any) -> np.ndarray:
    """A load as a wrench (6,) [force N; torque N.m]: a force (3,) or a wrench (6,), finite."""
    w = np.asarray(load, dtype=float).reshape(-1)
    if w.shape not in ((3,), (6,)) or not np.all(np.isfinite(w)):
        raise ParameterError(f"load: a force (3,) N or a wrench (6,) N and N.m, finite, got {load!r}")
    return np.r_[w, np.zeros(6 - len(w))]


def joint_compliance(mech: Any, q: Any, springs: Mapping[str, Any], output: str,
                     locked: Iterable[Any] = ()) -> np.ndarray:
    """The (6 + nv', 6 + nv') compliance of the output frame and of every joint (one
    :meth:`Mechanism.compliance <h4pin.mechanism.Mechanism.compliance>` call): its ``[:6, :6]``
    block is the output's, its ``[6:, :6]`` block maps the output's wrench to the joints' motions
    (:func:`joint_deflection`)."""
    from h4pin.mechanism.engine import JointOutput

    names = list(mech.model.names)[1:]
    return mech.compliance(q, springs, [output, *(JointOutput(n) for n in names)], locked)


def joint_deflection(mech: Any, q: Any, springs: Mapping[str, Any], output: str, load: Any,
                     locked: Iterable[Any] = (), compliance: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(dq (nv,), dy (6,))``: the joint motions and the output frame's motion (translation of
    its origin m, rotation rad, world axes) under ``load`` at the output frame's origin (force
    (3,) N or wrench (6,) N, N.m, world axes): ``dq = C[6:, :6] w``, ``dy = C[:6, :6] w`` with C
    :func:`joint_compliance` (``compliance``: that matrix, computed once by the caller). The
    deflected configuration is ``pin.integrate(model, q, dq)``."""
    w = wrench(load)
    C = joint_compliance(mech, q, springs, output, locked) if compliance is None else compliance
    return C[6:, :6] @ w, C[:6, :6] @ w


def field_points(ds: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(positions (n, 3) m, radii (n, 3) m/N, axes (n, 3, 3), worst (n,) m/N)`` of the grid
    points of status 0 of a motor-space atlas (:mod:`h4pin.mechanism.atlas`), read as stored."""
    if ds.attrs.get("kind") != "mechanism" or "compliance_axes" not in ds:
        raise ParameterError("atlas: a motor-space atlas (h4pin.mechanism.atlas), with compliance_axes")
    ok = (ds.status.values == 0).reshape(-1)
    n = ok.size
    pos = ds.position.values.reshape(n, 3)[ok]
    radii = ds.compliance_axes.values.reshape(n, 3)[ok]
    axes = ds.compliance_vectors.values.reshape(n, 3, 3)[ok]
    return pos, radii, axes, ds.compliance_max.values.reshape(n)[ok]


def draw_field(scene: Scene, ds: Any, size: float | None = None, path: str = "field") -> tuple[float, float]:
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
        size = float(np.median(near) / 2) if near.size else 0.05 * extent(scene.subject.model, scene.q)
    lo, hi = scene.field(pos, radii, axes, worst, size, path)
    scene.legend.append(f"field: {len(pos)} of {ds.status.size} grid points of the atlas, worst compliance "
                        f"{lo * 1e6:.3g} (dark) to {hi * 1e6:.3g} (yellow) um/N, radius {size * 1e3:.3g} mm for "
                        f"{hi * 1e6:.3g} um/N")
    return lo, hi


def draw_load(scene: Scene, load: Any, output: str, dq: np.ndarray, dy: np.ndarray,
              exaggeration: float | None = None) -> float:
    """The deflected robot (joint motions ``dq``, output motion ``dy``: :func:`joint_deflection`)
    as a red ghost, exaggerated (default: the output moves about 30 mm, or a tenth of the robot's
    size if smaller), and an arrow for the force at ``output``. Returns the exaggeration."""
    mech, q = scene.subject, scene.q
    w = wrench(load)
    moved = float(np.linalg.norm(dy[:3]))
    if exaggeration is None:
        exaggeration = nice(min(GHOST_SIZE, 0.1 * extent(mech.model, q)) / max(moved, 1e-15))
    scene.ghost(pin.integrate(mech.model, q, exaggeration * dq),
                f"red ghost: deflection under F = ({', '.join(f'{f:g}' for f in w[:3])}) N at {output}, "
                f"exaggerated x{exaggeration:g} (true |d{output}| = {moved * 1e6:.3g} um)")
    d = mech.model.createData()
    pin.framesForwardKinematics(mech.model, d, q)
    scene.force(d.oMf[mech.model.getFrameId(output)].translation, w[:3])
    return exaggeration


def draw_equilibrium(scene: Scene, eq: Any, output: str, load: Any = None, exaggeration: float | None = None) -> float:
    """The robot in a loaded equilibrium (:meth:`Mechanism.equilibrium
    <h4pin.mechanism.Mechanism.equilibrium>`) as a red ghost, its motion from the rest state
    exaggerated (default: the output moves about 30 mm, or a tenth of the robot's size if
    smaller), and an arrow for ``load`` at ``output``. Returns the exaggeration."""
    mech = scene.subject
    moved = float(np.linalg.norm(eq.displacement(output)[:3]))
    if exaggeration is None:
        exaggeration = nice(min(GHOST_SIZE, 0.1 * extent(mech.model, eq.rest)) / max(moved, 1e-15))
    dq = pin.difference(mech.model, eq.rest, eq.q)
    scene.ghost(pin.integrate(mech.model, eq.rest, exaggeration * dq),
                f"red ghost: loaded equilibrium (its weight{'' if load is None else ' and the load'}), exaggerated "
                f"x{exaggeration:g} (true |d{output}| = {moved * 1e6:.3g} um{'' if eq.stable else ', unstable'})")
    if load is not None:
        d = mech.model.createData()
        pin.framesForwardKinematics(mech.model, d, eq.rest)
        scene.force(d.oMf[mech.model.getFrameId(output)].translation, wrench(load)[:3])
    return exaggeration


def show(mech: Any, q: Any = None, springs: Mapping[str, Any] | None = None, output: str | None = None,
         locked: Iterable[Any] = (), *, atlas: Any = None, load: Any = None, scale: float | None = None,
         size: float | None = None, exaggeration: float | None = None, vis: meshcat.Visualizer | None = None,
         host: str = meshcat_server.LOCALHOST, gravity: bool = False, payload: Any = None) -> Scene:
    """Any closed-loop robot in a new meshcat server: its stick drawing at ``q`` (default the
    reference assembly), the compliance ellipsoid at ``output`` (``scale`` mm per um/N), the
    ellipsoid field of ``atlas`` (:func:`draw_field`, ``size``) and the deflected shape under
    ``load`` (:func:`draw_load`, ``exaggeration``), from one compliance (:func:`joint_compliance`);
    with ``gravity`` (and a ``payload`` ``Payload`` at the output), the loaded equilibrium under
    the robot's weight and ``load`` instead (:func:`draw_equilibrium`).
    ``springs``, ``output`` and ``locked`` default to the atlas's (its attributes).
    ``html()``/``write_html(path)``: a self-contained page; ``close()`` stops the server.

    Raises:
        ParameterError: not a mechanism, no output frame, a load without springs, a bad load; as
            :meth:`h4pin.mechanism.Mechanism.compliance` (before any server starts).
    """
    from h4pin.mechanism.core import Mechanism

    if not isinstance(mech, Mechanism):
        raise ParameterError(f"mechanism: an h4pin.mechanism.Mechanism, got {type(mech).__name__}")
    if atlas is not None:
        field_points(atlas)
        springs = json.loads(atlas.attrs["springs"]) if springs is None else springs
        output = atlas.attrs["output"] if output is None else output
        locked = tuple(locked) or tuple(json.loads(atlas.attrs.get("locked", "[]")))
    if load is not None or gravity:
        if load is not None:
            wrench(load)
        if springs is None or output is None:
            raise ParameterError("load, gravity: give the springs and the output frame (or an atlas that holds them)")
    q = mech.assemble() if q is None else mech.configuration(q)
    eq = None
    if gravity:
        eq = mech.equilibrium(q, springs, None if load is None else {output: wrench(load)}, gravity=True,
                              payload=None if payload is None else (output, payload), locked=locked)
    C = None
    if springs is not None and output is not None:
        C = joint_compliance(mech, q, springs, output, locked) if load is not None and not gravity else \
            mech.compliance(q, springs, [output], locked)
    scene = Scene(mech, vis, host)
    try:
        scene.legend.append(f"{mech.name}: {mech.model.njoints - 1} joints, {len(mech.constraint_models)} closures")
        scene.draw(q)
        if C is not None:
            d = mech.model.createData()
            pin.framesForwardKinematics(mech.model, d, q)
            scene.compliance(C[:3, :3], d.oMf[mech.model.getFrameId(output)].translation, scale,
                             "mechanism/ellipsoid", output)
        if atlas is not None:
            draw_field(scene, atlas, size)
        if eq is not None:
            draw_equilibrium(scene, eq, output, load, exaggeration)
        elif load is not None:
            dq, dy = joint_deflection(mech, q, springs, output, load, locked, C)
            draw_load(scene, load, output, dq, dy, exaggeration)
    except BaseException:
        scene.close()
        raise
    return scene


__all__ = ["ARROW_LENGTH", "ELLIPSOID_SIZE", "GHOST_SIZE", "MAX_ELLIPSOIDS", "Scene", "draw_ellipsoid", "draw_field",
           "draw_equilibrium", "draw_load", "draw_sticks", "ellipsoid_axes", "extent", "field_points", "hex_color",
           "joint_compliance", "joint_deflection", "nice", "screenshot", "show", "wrench"]
