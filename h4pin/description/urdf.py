# SPDX-License-Identifier: Apache-2.0
"""H4 URDF: writer of nominal robots, and reader of the custom elements of any H4 URDF.

:func:`to_urdf` writes the kinematic tree of an H4 described by :class:`h4pin.H4Params` as plain
URDF, plus custom elements that make one file a complete model (Pinocchio and yourdfpy accept and
ignore them; h4pin reads them with an XML parser, :func:`parse`):

* eight ``<constraint type="point">`` elements, one per bar, closing bar ``ij`` on its lateral
  bar at ``B_ij``. Their form (``<parent link>``, ``<parent_origin>``, ``<child link>``,
  ``<child_origin>``) follows the ``<constraint>`` element proposed to ROS urdfdom;
* spring data next to the element it belongs to: ``<h4_actuator kc=.../>`` inside each actuated
  ``<joint>``, ``<h4_forearm E= I= G= I0= stressed_fraction=/>`` inside each forearm ``<link>``,
  ``<h4_bar Sb= Eb=/>`` inside each bar ``<link>``. Editing a joint, or copying a leg, takes its
  data along, and a tree cannot disagree with a table kept elsewhere;
* optional data of the elements eq. 30 neglects (:mod:`h4pin.description.elements`, off when absent):
  ``<h4_revolute radial= axial= tilt=/>`` inside each lateral revolute ``<joint>``,
  ``<h4_ball radial=/>`` inside each bar ``<link>`` (both ball joints of the bar),
  ``<h4_plate_bar EI_n= GJ_n=/>`` inside the central bar's ``<link>`` (segment D-C_n) and each
  lateral bar's ``<link>`` (arm C_k-B_n of leg n), ``shaft_tilt=`` on ``<h4_actuator>`` and
  ``<h4_base translation= rotation=/>`` inside each actuated ``<joint>``, ``out_EI=`` on
  ``<h4_forearm>`` (the forearm's bending out of its plane);
* ``<h4pin format="2" units="SI"/>``: the version of these conventions and the units.

Geometry is never read from a side element: :func:`h4pin.load` takes every length and position
from the tree and the closures (:mod:`h4pin.description.geometry`).

The tree written here (reference configuration: all joint angles zero, world-aligned frames):

* ``base_link`` with the actuators drawn at ``P_i``;
* per leg i: revolute ``actuator_i`` (axis u_i at P_i) -> ``forearm_i`` (along a_i = u_i x z,
  length r_i); per bar ij a universal joint made of two revolutes ``bar_ij_u1`` (axis u_i) and
  ``bar_ij_u2`` (axis a_i) at A_ij -> ``bar_ij``, hanging along -z with its end at (0, 0, -l_ij).
  (Pinocchio's URDF parser has no ball joint; the spin of a bar about its axis is idle.)
* the travelling plate as a floating subtree: ``floating`` joint ``plate`` -> ``central_bar``
  (origin D), and revolute-z joints ``lateral_k`` at C_k -> ``lateral_bar_k``.
* named frames (massless links on fixed joints): P_i, A_i, A_ij, B_i, B_ij, C_k, D, bar_ij_end.

Materials for the inertias (stated, not in the paper): forearms are aluminium (2700 kg/m^3)
solid rods whose radius gives the paper's I; bars are carbon-fibre tubes (1600 kg/m^3) of
section Sb; the plate is aluminium rods; each universal-joint cross is a 20 g steel part.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from h4pin.description.elements import PLACES, Elements, Kind, kinds
from h4pin.description.geometry import ACTUATOR_LIMITS, LATERAL_LIMITS
from h4pin.description.params import LEG_LATERAL, H4Params
from h4pin.errors import MalformedURDFError
from h4pin.files import write_text
from h4pin.mechanism.urdf_reader import attribute as _attr
from h4pin.mechanism.urdf_reader import check_tree as _check_tree
from h4pin.mechanism.urdf_reader import decode  # noqa: F401  (h4pin.robot reads a URDF's bytes with it)
from h4pin.mechanism.urdf_reader import floats as _floats
from h4pin.mechanism.urdf_reader import parse as _parse

FORMAT_VERSION = "2"
RHO_ALUMINIUM = 2700.0  # kg/m^3
RHO_CARBON = 1600.0  # kg/m^3
CROSS_MASS = 0.02  # kg
BAR_RADIUS = 5e-3  # m, outer radius of the bar tubes (drawing and inertia)
PLATE_RADIUS = 8e-3  # m, radius of the plate rods (drawing and inertia)


def leg_names(i: int) -> dict[str, str]:
    """URDF names for leg ``i`` (1-based)."""
    return {"joint": f"actuator_{i}", "forearm": f"forearm_{i}", "P": f"P_{i}", "A": f"A_{i}", "B": f"B_{i}"}


def bar_names(i: int, j: int) -> dict[str, str]:
    """URDF names for bar ``ij`` (1-based)."""
    s = f"{i}{j}"
    return {
        "u1": f"bar_{s}_u1",
        "u2": f"bar_{s}_u2",
        "cross": f"bar_{s}_cross",
        "bar": f"bar_{s}",
        "end": f"bar_{s}_end",
        "A": f"A_{s}",
        "B": f"B_{s}",
        "closure": f"closure_{s}",
    }


def lateral_names(k: int) -> dict[str, str]:
    """URDF names for lateral bar ``k`` (1-based)."""
    return {"joint": f"lateral_{k}", "link": f"lateral_bar_{k}", "C": f"C_{k}"}


def _num(x: float) -> str:
    x = float(x)
    return "0" if x == 0.0 else repr(x)


def _vec(v: np.ndarray) -> str:
    return " ".join(_num(c) for c in v)


def _rpy_z_to(d: np.ndarray) -> np.ndarray:
    """Roll-pitch-yaw of a rotation taking +z to the unit vector ``d`` (for cylinders)."""
    d = d / np.linalg.norm(d)
    pitch = np.arccos(np.clip(d[2], -1.0, 1.0))
    yaw = np.arctan2(d[1], d[0]) if np.hypot(d[0], d[1]) > 1e-12 else 0.0
    return np.array([0.0, pitch, yaw])


class _Body:
    """Collects the primitive shapes of one link and computes its inertial."""

    def __init__(self) -> None:
        self.shapes: list[tuple[str, np.ndarray, np.ndarray, str]] = []
        self.masses: list[tuple[float, np.ndarray, np.ndarray]] = []  # mass, com, inertia at com

    def rod(self, a: np.ndarray, b: np.ndarray, radius: float, rho: float, hollow: float = 0.0) -> None:
        """A cylinder from a to b; ``hollow`` is the inner radius (0: solid)."""
        d = np.asarray(b, float) - np.asarray(a, float)
        length = float(np.linalg.norm(d))
        if length < 1e-9:
            return
        u = d / length
        mid = (np.asarray(a) + np.asarray(b)) / 2
        self.shapes.append(("cylinder", mid, _rpy_z_to(u), f'radius="{_num(radius)}" length="{_num(length)}"'))
        m = rho * np.pi * (radius**2 - hollow**2) * length
        axial = 0.5 * m * (radius**2 + hollow**2)
        perp = m * (3 * (radius**2 + hollow**2) + length**2) / 12
        self.masses.append((m, mid, perp * (np.eye(3) - np.outer(u, u)) + axial * np.outer(u, u)))

    def ball(self, c: np.ndarray, radius: float, mass: float = 0.0) -> None:
        self.shapes.append(("sphere", np.asarray(c, float), np.zeros(3), f'radius="{_num(radius)}"'))
        if mass > 0:
            self.masses.append((mass, np.asarray(c, float), 0.4 * mass * radius**2 * np.eye(3)))

    def inertial(self) -> tuple[float, np.ndarray, np.ndarray]:
        """The link's mass (kg), centre of mass (3,) and inertia about it (3, 3) in its frame."""
        if not self.masses:
            return 0.0, np.zeros(3), np.zeros((3, 3))
        m = sum(mi for mi, _, _ in self.masses)
        com = sum(mi * ci for mi, ci, _ in self.masses) / m
        inertia = sum(ii + mi * (np.dot(ci - com, ci - com) * np.eye(3) - np.outer(ci - com, ci - com))
                      for mi, ci, ii in self.masses)
        return m, com, inertia

    def xml(self, name: str, material: str, extra: str = "") -> str:
        out = [f'  <link name="{name}">']
        if extra:
            out.append(f"    {extra}")
        if self.masses:
            m, com, inertia = self.inertial()
            ixx, ixy, ixz = inertia[0]
            iyy, iyz, izz = inertia[1, 1], inertia[1, 2], inertia[2, 2]
            out += [
                "    <inertial>",
                f'      <origin xyz="{_vec(com)}" rpy="0 0 0"/>',
                f'      <mass value="{_num(m)}"/>',
                f'      <inertia ixx="{_num(ixx)}" ixy="{_num(ixy)}" ixz="{_num(ixz)}" '
                f'iyy="{_num(iyy)}" iyz="{_num(iyz)}" izz="{_num(izz)}"/>',
                "    </inertial>",
            ]
        for kind in ("visual", "collision"):
            for shape, xyz, rpy, attrs in self.shapes:
                out += [
                    f"    <{kind}>",
                    f'      <origin xyz="{_vec(xyz)}" rpy="{_vec(rpy)}"/>',
                    f"      <geometry><{shape} {attrs}/></geometry>",
                ]
                if kind == "visual":
                    out.append(f'      <material name="{material}"/>')
                out.append(f"    </{kind}>")
        out.append("  </link>")
        return "\n".join(out)


def _joint(name: str, kind: str, parent: str, child: str, xyz: np.ndarray, axis: np.ndarray | None = None,
           limits: tuple[float, float] | None = None, extra: str = "") -> str:
    out = [f'  <joint name="{name}" type="{kind}">', f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
           f'    <origin xyz="{_vec(xyz)}" rpy="0 0 0"/>']
    if axis is not None:
        out.append(f'    <axis xyz="{_vec(axis)}"/>')
    if limits is not None:
        out.append(f'    <limit lower="{_num(limits[0])}" upper="{_num(limits[1])}" effort="1000" velocity="20"/>')
    if extra:
        out.append(f"    {extra}")
    out.append("  </joint>")
    return "\n".join(out)


def _frame(name: str, parent: str, xyz: np.ndarray) -> str:
    """A named frame: a massless link on a fixed joint."""
    return f'  <link name="{name}"/>\n' + _joint(f"{name}_frame", "fixed", parent, name, xyz)


def _element_data(elements: Elements | None, place: str, indices: Any, tags: dict[str, dict[str, str]] | None = None
                  ) -> str:
    """The data tags of a URDF element that holds ``place``'s (:data:`h4pin.description.elements.PLACES`)
    elements ``indices`` (0-based): ``<tag attr="..."/>`` of each schema row's value that is on
    (``attr_n``, n = index + 1, where the place holds several), merged into ``tags`` (tag ->
    attribute -> text, e.g. a spring tag's own attributes)."""
    tags = {} if tags is None else tags
    for k in () if elements is None else elements.kinds_on():
        if k.place != place:
            continue
        tag, attr = k.urdf
        for s in indices:
            value = getattr(elements, k.name)[s]
            if value != k.off:
                tags.setdefault(tag, {})[f"{attr}_{s + 1}" if PLACES[place][2] else attr] = _num(value)
    return "\n    ".join("<" + " ".join([tag, *(f'{a}="{v}"' for a, v in attrs.items())]) + "/>"
                          for tag, attrs in tags.items())


def _forearm(p: H4Params, i: int) -> _Body:
    """Forearm i: a solid round rod P_i -> A_i (second moment I), the cross-piece A_i1-A_i2 and
    the two ball joints, in its joint's frame (origin P_i, world axes at q = 0)."""
    a, u, h, r = p.forearm_dirs[:, i], p.U[:, i], p.half_width[i], p.r[i]
    radius = (4.0 * p.I[i] / np.pi) ** 0.25  # solid round section with second moment I
    body = _Body()
    body.rod(np.zeros(3), r * a, radius, RHO_ALUMINIUM)
    body.rod(r * a - h * u, r * a + h * u, radius * 0.6, RHO_ALUMINIUM)
    for s in (1.0, -1.0):
        body.ball(r * a + s * h * u, p.ball_radius)
    return body


def _cross(p: H4Params) -> _Body:
    """A universal joint's cross (a small ball of :data:`CROSS_MASS`) at its centre A_ij."""
    body = _Body()
    body.ball(np.zeros(3), p.ball_radius * 0.5, CROSS_MASS)
    return body


def _bar(p: H4Params, n: int) -> _Body:
    """Bar n: a carbon tube from A_ij (its frame's origin) to the bar end at (0, 0, -l) (its
    frame at the neutral configuration: world axes), of cross-section Sb."""
    body = _Body()
    inner = np.sqrt(max(BAR_RADIUS**2 - p.Sb[n] / np.pi, 0.0))
    body.rod(np.zeros(3), np.array([0.0, 0.0, -p.l[n]]), BAR_RADIUS, RHO_CARBON, inner)
    return body


def _central(p: H4Params) -> _Body:
    """The central bar: the rods C_1-C_2 and D-(C_1 + C_2)/2 and a ball at D (its frame's origin)."""
    body = _Body()
    body.rod(p.DC[:, 0], p.DC[:, 1], PLATE_RADIUS, RHO_ALUMINIUM)
    body.rod(np.zeros(3), p.DC.mean(axis=1), PLATE_RADIUS, RHO_ALUMINIUM)
    body.ball(np.zeros(3), 1.5 * PLATE_RADIUS)
    return body


def _lateral(p: H4Params, k: int, bij: np.ndarray) -> _Body:
    """Lateral bar k: from C_k (its frame's origin) a rod to each of its legs' B_i, a rod B_i1-B_i2
    and the ball joints."""
    body = _Body()
    for i in np.flatnonzero(LEG_LATERAL == k):
        body.rod(np.zeros(3), p.DB[:, i] - p.DC[:, k], PLATE_RADIUS, RHO_ALUMINIUM)
        body.rod(bij[i, 0] - p.DC[:, k], bij[i, 1] - p.DC[:, k], PLATE_RADIUS, RHO_ALUMINIUM)
        for j in range(2):
            body.ball(bij[i, j] - p.DC[:, k], p.ball_radius)
    return body


@dataclasses.dataclass(frozen=True)
class MassModel:
    """The moving links of the robot :func:`to_urdf` writes for some :class:`H4Params`, as that
    URDF gives them: every joint's origin (in its parent link's frame; every frame has the world's
    axes at the neutral configuration) and axis, and each link's (mass, centre of mass, inertia
    about it) in its frame. Legs i (4): actuator origin P_i, axis u_i, the forearm. Bars n (8):
    the universal joint at A_ij (in the forearm's frame) about u_i then a_i = forearm direction,
    the cross, the bar, the bar's end (0, 0, -l). The central bar (its frame at D), lateral bars k
    (2): origin C_k - D, axis z."""

    actuator_origin: np.ndarray  # (4, 3)
    actuator_axis: np.ndarray  # (4, 3)
    forearm: tuple
    anchor: np.ndarray  # (8, 3)
    u1_axis: np.ndarray  # (8, 3)
    u2_axis: np.ndarray  # (8, 3)
    cross: tuple
    bar: tuple
    bar_end: np.ndarray  # (8, 3)
    central: tuple
    lateral_origin: np.ndarray  # (2, 3)
    lateral: tuple


def mass_model(params: H4Params) -> MassModel:
    """The :class:`MassModel` of the URDF :func:`to_urdf` writes for ``params`` (without writing
    it: the design sweep's natural frequencies take it per design, :mod:`h4pin.stiffness.frequencies`)."""
    p = params
    a, u = p.forearm_dirs.T, p.U.T
    signs = np.tile([1.0, -1.0], 4)
    legs = np.repeat(np.arange(4), 2)
    bij = p.plate_ball_centres()
    cross = _cross(p).inertial()
    return MassModel(actuator_origin=p.P.T.copy(), actuator_axis=u.copy(),
                     forearm=tuple(_forearm(p, i).inertial() for i in range(4)),
                     anchor=p.r[legs, None] * a[legs] + (signs * p.half_width[legs])[:, None] * u[legs],
                     u1_axis=u[legs], u2_axis=a[legs], cross=(cross,) * 8,
                     bar=tuple(_bar(p, n).inertial() for n in range(8)),
                     bar_end=np.stack([np.zeros(8), np.zeros(8), -p.l], axis=1), central=_central(p).inertial(),
                     lateral_origin=p.DC.T.copy(), lateral=tuple(_lateral(p, k, bij).inertial() for k in range(2)))


def to_urdf(params: H4Params, name: str = "h4", elements: Elements | None = None) -> str:
    """URDF text of the H4 described by ``params`` (see the module docstring for its layout).

    ``elements``: data of the neglected elements (:class:`h4pin.description.elements.Elements`) to write
    inline (``<h4_revolute>`` in the lateral joints, ``<h4_ball>`` in the bar links); none by
    default. The text is deterministic: the same parameters always give the same bytes.
    """
    p = params
    a = p.forearm_dirs.T
    u = p.U.T
    signs = (1.0, -1.0)
    parts: list[str] = []

    base = _Body()
    for i in range(4):
        base.rod(p.P[:, i] - 0.04 * u[i], p.P[:, i] + 0.04 * u[i], 0.05, RHO_ALUMINIUM)
    parts.append(base.xml("base_link", "frame"))
    for i in range(4):
        n = leg_names(i + 1)
        h, r = p.half_width[i], p.r[i]
        parts.append(_frame(n["P"], "base_link", p.P[:, i]))
        spring = {"h4_forearm": {"E": _num(p.E[i]), "I": _num(p.I[i]), "G": _num(p.G[i]), "I0": _num(p.I0[i]),
                                 "stressed_fraction": _num(p.forearm_stressed_fraction[i])}}
        parts.append(_forearm(p, i).xml(n["forearm"], "forearm", _element_data(elements, "forearm_link", [i], spring)))
        actuator = _element_data(elements, "actuated_joint", [i], {"h4_actuator": {"kc": _num(p.kc[i])}})
        parts.append(_joint(n["joint"], "revolute", "base_link", n["forearm"], p.P[:, i], u[i], ACTUATOR_LIMITS,
                            actuator))
        parts.append(_frame(n["A"], n["forearm"], r * a[i]))
        for j, s in enumerate(signs):
            b = bar_names(i + 1, j + 1)
            nb = 2 * i + j
            anchor = r * a[i] + s * h * u[i]
            parts.append(_frame(b["A"], n["forearm"], anchor))
            parts.append(_cross(p).xml(b["cross"], "joint"))
            parts.append(_joint(b["u1"], "revolute", n["forearm"], b["cross"], anchor, u[i], (-np.pi, np.pi)))
            bar_data = {"h4_bar": {"Sb": _num(p.Sb[nb]), "Eb": _num(p.Eb[nb])}}
            parts.append(_bar(p, nb).xml(b["bar"], "bar", _element_data(elements, "bar_link", [nb], bar_data)))
            parts.append(_joint(b["u2"], "revolute", b["cross"], b["bar"], np.zeros(3), a[i], (-np.pi, np.pi)))
            parts.append(_frame(b["end"], b["bar"], np.array([0.0, 0.0, -p.l[nb]])))

    parts.append(_central(p).xml("central_bar", "plate", _element_data(elements, "central_link", range(2))))
    parts.append(_joint("plate", "floating", "base_link", "central_bar", np.zeros(3)))
    parts.append(_frame("D", "central_bar", np.zeros(3)))
    bij = p.plate_ball_centres()
    for k in range(2):
        n = lateral_names(k + 1)
        parts.append(_lateral(p, k, bij).xml(n["link"], "plate",
                                             _element_data(elements, "lateral_link", np.flatnonzero(LEG_LATERAL == k))))
        joint_data = _element_data(elements, "lateral_joint", [k])
        parts.append(_joint(n["joint"], "revolute", "central_bar", n["link"], p.DC[:, k], np.array([0.0, 0.0, 1.0]),
                            LATERAL_LIMITS, joint_data))
        parts.append(_frame(n["C"], n["link"], np.zeros(3)))
        for i in np.flatnonzero(LEG_LATERAL == k):
            parts.append(_frame(leg_names(i + 1)["B"], n["link"], p.DB[:, i] - p.DC[:, k]))
            for j in range(2):
                parts.append(_frame(bar_names(i + 1, j + 1)["B"], n["link"], bij[i, j] - p.DC[:, k]))

    closures = []
    for i in range(4):
        k = LEG_LATERAL[i]
        for j in range(2):
            b = bar_names(i + 1, j + 1)
            closures.append(
                f'  <constraint name="{b["closure"]}" type="point">\n'
                f'    <parent link="{b["bar"]}"/>\n'
                f'    <parent_origin xyz="0 0 {_num(-p.l[2 * i + j])}"/>\n'
                f'    <child link="{lateral_names(k + 1)["link"]}"/>\n'
                f'    <child_origin xyz="{_vec(bij[i, j] - p.DC[:, k])}"/>\n'
                "  </constraint>"
            )

    materials = {"frame": "0.35 0.37 0.40 1", "forearm": "0.80 0.45 0.15 1", "bar": "0.15 0.15 0.17 1",
                 "joint": "0.6 0.6 0.6 1", "plate": "0.20 0.45 0.80 1"}
    header = [
        '<?xml version="1.0"?>',
        f"<!-- H4 parallel robot '{name}', written by h4pin.description.urdf.to_urdf "
        "(edit freely: the file is the model). -->",
        f'<robot name="{name}">',
        *(f'  <material name="{m}"><color rgba="{c}"/></material>' for m, c in materials.items()),
    ]
    marker = f'  <h4pin format="{FORMAT_VERSION}" units="SI"/>'
    return "\n".join([*header, marker, *parts, *closures, "</robot>", ""])


#: Spring data elements: tag -> (where it sits, its attributes -> the H4Params field). The
#: optional elements' tags are their schema rows' (:func:`data_tags`).
SPRING_ELEMENTS = {
    "h4_actuator": ("joint", {"kc": "kc"}),
    "h4_forearm": ("link", {"E": "E", "I": "I", "G": "G", "I0": "I0",
                            "stressed_fraction": "forearm_stressed_fraction"}),
    "h4_bar": ("link", {"Sb": "Sb", "Eb": "Eb"}),
}


def element_field(kind: Kind, s: int) -> str:
    """The key under which :func:`parse` reads element s of ``kind`` (:attr:`URDFExtras.springs`):
    ``"<tag attr>"``, or ``"<tag attr_n>"`` (n = s + 1) where its place holds several."""
    tag, attr = kind.urdf
    return f"<{tag} {attr}_{s + 1}>" if PLACES[kind.place][2] else f"<{tag} {attr}>"


def data_tags() -> dict[str, tuple[str, dict[str, str]]]:
    """Every data tag a URDF may hold: tag -> (``joint`` or ``link``, attribute -> field), the
    springs' (:data:`SPRING_ELEMENTS`) and each schema row's (:func:`element_field`)."""
    out = {tag: (where, dict(fields)) for tag, (where, fields) in SPRING_ELEMENTS.items()}
    for k in kinds():
        fields = out.setdefault(k.urdf[0], (PLACES[k.place][1], {}))[1]
        for s in range(k.count):
            fields[element_field(k, s)[len(k.urdf[0]) + 2:-1]] = element_field(k, s)
    return out


@dataclasses.dataclass(frozen=True)
class Closure:
    """One ``<constraint type="point">``: the point ``parent_xyz`` of link ``parent`` coincides
    with the point ``child_xyz`` of link ``child`` (each in its link's frame, m)."""

    name: str
    parent: str
    parent_xyz: np.ndarray
    child: str
    child_xyz: np.ndarray


@dataclasses.dataclass(frozen=True)
class URDFExtras:
    """What h4pin reads from the custom elements of an H4 URDF (:func:`parse`).

    Attributes:
        closures: the ``<constraint>`` elements, in file order.
        springs: ``{element name: {field: value}}`` for joints (kc; the optional revolute
            element data) and links (forearm, bar data; the optional ball-joint data).
        joint_child: ``{joint name: child link name}``.
    """

    closures: list[Closure]
    springs: dict[str, dict[str, float]]
    joint_child: dict[str, str]


def parse(text: str, where: str = "URDF") -> URDFExtras:
    """Read and check the custom elements of an H4 URDF: closures, spring data, format.

    Raises:
        MalformedURDFError: naming ``where`` and the element: not XML, not a ``<robot>``, an
            ``<h4pin>`` marker with another format or units than SI, a closure that is not of
            type ``point``, duplicated closure names, a spring datum that is not a number.
    """
    root = _parse(text, where)
    if root.find("h4_parameters") is not None:
        raise MalformedURDFError(f"{where}: <h4_parameters> is h4pin's format 1, which kept the geometry beside "
                                 "the tree; regenerate the file (h4pin.description.urdf.write_urdf or "
                                 "scripts/generate_urdf.py)")
    for marker in root.findall("h4pin"):
        if marker.get("format", FORMAT_VERSION) != FORMAT_VERSION:
            raise MalformedURDFError(f"{where}: <h4pin format=\"{marker.get('format')}\"> is unknown; this h4pin "
                                     f"reads format {FORMAT_VERSION}")
        if marker.get("units", "SI") != "SI":
            raise MalformedURDFError(f"{where}: <h4pin units=\"{marker.get('units')}\">: only SI (m, N, Pa) is "
                                     "supported")
    _check_tree(root, where)
    closures, names = [], set()
    for c in root.findall("constraint"):
        name = _attr(c, "name", where, "a <constraint>")
        if c.get("type") != "point":
            raise MalformedURDFError(f"{where}: <constraint name=\"{name}\"> has type {c.get('type')!r}; the H4's "
                                     "closures are 3-D point constraints (type=\"point\")")
        if name in names:
            raise MalformedURDFError(f"{where}: two <constraint> elements are named '{name}'")
        names.add(name)
        sides = []
        for side in ("parent", "child"):
            link = _attr(c.find(side), "link", where, f"<{side}> of closure '{name}'")
            origin = c.find(f"{side}_origin")
            xyz = np.zeros(3) if origin is None else _floats(origin.get("xyz", "0 0 0"), 3, where,
                                                              f"<{side}_origin> of closure '{name}'")
            sides += [link, xyz]
        closures.append(Closure(name, *sides))
    springs: dict[str, dict[str, float]] = {}
    for tag, (kind, fields) in data_tags().items():
        other = "link" if kind == "joint" else "joint"
        for elem in root.findall(other):
            if elem.find(tag) is not None:
                raise MalformedURDFError(f"{where}: <{tag}> sits in {other} '{elem.get('name')}'; it belongs inside "
                                         f"a <{kind}>")
        for elem in root.findall(kind):
            found = elem.findall(tag)
            if not found:
                continue
            owner = _attr(elem, "name", where, f"a <{kind}>")
            if len(found) > 1:
                raise MalformedURDFError(f"{where}: {kind} '{owner}' has {len(found)} <{tag}> elements")
            data = springs.setdefault(owner, {})
            for key, field in fields.items():
                raw = found[0].get(key)
                if raw is None:
                    continue
                data[field] = float(_floats(raw, 1, where, f"<{tag} {key}> of {kind} '{owner}'")[0])
    joint_child = {}
    for j in root.findall("joint"):
        child = j.find("child")
        if child is not None and j.get("name") is not None:
            joint_child[j.get("name")] = child.get("link")
    return URDFExtras(closures, springs, joint_child)


def closures_from_urdf(text: str, where: str = "URDF") -> list[tuple[str, str, np.ndarray, str, np.ndarray]]:
    """The ``<constraint>`` elements as (name, parent link, parent xyz, child link, child xyz)."""
    return [(c.name, c.parent, c.parent_xyz, c.child, c.child_xyz) for c in parse(text, where).closures]


def write_urdf(params: H4Params, path: str | Path, name: str | None = None) -> Path:
    """Write ``to_urdf(params)`` to ``path`` atomically (mode 0644; no half-written file)."""
    path = Path(path)
    return write_text_atomic(path, to_urdf(params, name or path.stem))


def write_text_atomic(path: str | Path, text: str, *, mark: bool = True) -> Path:
    """Write ``text`` to ``path`` atomically, mode 0644 (:func:`h4pin.files.write_text`; ``mark``:
    with its digest comment, off for the files the project ships)."""
    return write_text(path, text, mark=mark)
