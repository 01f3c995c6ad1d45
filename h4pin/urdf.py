# SPDX-License-Identifier: Apache-2.0
"""H4 parameters <-> URDF with loop closures.

:func:`to_urdf` writes the kinematic tree of an H4 as plain URDF, plus two custom elements that
make one file a complete description of a variant:

* eight ``<constraint type="point">`` elements, one per bar, closing bar ``ij`` on its lateral
  bar at ``B_ij``. Their form (``<parent link>``, ``<parent_origin>``, ``<child link>``,
  ``<child_origin>``) follows the ``<constraint>`` element proposed to ROS urdfdom;
* one ``<h4_parameters>`` element holding every field of :class:`h4pin.H4Params` (geometry and
  the spring data kc, E, I, G, I0, Sb, Eb) with 17 significant digits, so
  ``params_from_urdf(to_urdf(p)) == p`` exactly.

Pinocchio and yourdfpy both accept (and ignore) the custom elements; h4pin reads them with an
XML parser. :func:`params_from_urdf` also checks that the tree agrees with ``<h4_parameters>``
and raises :class:`h4pin.MalformedURDFError` naming what is missing or inconsistent.

The tree (reference configuration: all joint angles zero, world-aligned frames):

* ``base_link`` with the actuators drawn at ``P_i``;
* per leg i: revolute ``actuator_i`` (axis u_i at P_i) -> ``forearm_i`` (along a_i = u_i x z,
  length r); per bar ij a universal joint made of two revolutes ``bar_ij_u1`` (axis u_i) and
  ``bar_ij_u2`` (axis a_i) at A_ij -> ``bar_ij``, hanging along -z with its end at (0, 0, -l).
  (Pinocchio's URDF parser has no ball joint; the spin of a bar about its axis is idle.)
* the travelling plate as a floating subtree: ``floating`` joint ``plate`` -> ``central_bar``
  (origin D), and revolute-z joints ``lateral_k`` at C_k -> ``lateral_bar_k``.
* named frames (massless links on fixed joints): P_i, A_i, A_ij, B_i, B_ij, C_k, D, bar_ij_end.

Materials for the inertias (stated, not in the paper): forearms are aluminium (2700 kg/m^3)
solid rods whose radius gives the paper's I; bars are carbon-fibre tubes (1600 kg/m^3) of
section Sb; the plate is aluminium rods; each universal-joint cross is a 20 g steel part.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from h4pin.errors import MalformedURDFError
from h4pin.params import LEG_LATERAL, H4Params

FORMAT_VERSION = "1"
RHO_ALUMINIUM = 2700.0  # kg/m^3
RHO_CARBON = 1600.0  # kg/m^3
CROSS_MASS = 0.02  # kg
BAR_RADIUS = 5e-3  # m, outer radius of the bar tubes (drawing and inertia)
PLATE_RADIUS = 8e-3  # m, radius of the plate rods (drawing and inertia)
ACTUATOR_LIMITS = (-1.0, 2.0)  # rad, joint limits written for the actuators


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

    def xml(self, name: str, material: str) -> str:
        out = [f'  <link name="{name}">']
        if self.masses:
            m = sum(mi for mi, _, _ in self.masses)
            com = sum(mi * ci for mi, ci, _ in self.masses) / m
            inertia = sum(
                ii + mi * (np.dot(ci - com, ci - com) * np.eye(3) - np.outer(ci - com, ci - com))
                for mi, ci, ii in self.masses
            )
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
           limits: tuple[float, float] | None = None) -> str:
    out = [f'  <joint name="{name}" type="{kind}">', f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
           f'    <origin xyz="{_vec(xyz)}" rpy="0 0 0"/>']
    if axis is not None:
        out.append(f'    <axis xyz="{_vec(axis)}"/>')
    if limits is not None:
        out.append(f'    <limit lower="{_num(limits[0])}" upper="{_num(limits[1])}" effort="1000" velocity="20"/>')
    out.append("  </joint>")
    return "\n".join(out)


def _frame(name: str, parent: str, xyz: np.ndarray) -> str:
    """A named frame: a massless link on a fixed joint."""
    return f'  <link name="{name}"/>\n' + _joint(f"{name}_frame", "fixed", parent, name, xyz)


def to_urdf(params: H4Params, name: str = "h4") -> str:
    """URDF text of the H4 described by ``params`` (see the module docstring for its layout).

    The text is deterministic: the same parameters always give the same bytes.
    """
    p = params
    a = p.forearm_dirs.T
    u = p.U.T
    h = p.half_width
    signs = (1.0, -1.0)
    forearm_radius = (4.0 * p.I / np.pi) ** 0.25  # solid round section with second moment I
    bar_inner = np.sqrt(max(BAR_RADIUS**2 - p.Sb / np.pi, 0.0))
    parts: list[str] = []

    base = _Body()
    for i in range(4):
        base.rod(p.P[:, i] - 0.04 * u[i], p.P[:, i] + 0.04 * u[i], 0.05, RHO_ALUMINIUM)
    parts.append(base.xml("base_link", "frame"))
    for i in range(4):
        n = leg_names(i + 1)
        parts.append(_frame(n["P"], "base_link", p.P[:, i]))
        forearm = _Body()
        forearm.rod(np.zeros(3), p.r * a[i], forearm_radius, RHO_ALUMINIUM)
        forearm.rod(p.r * a[i] - h * u[i], p.r * a[i] + h * u[i], forearm_radius * 0.6, RHO_ALUMINIUM)
        for s in signs:
            forearm.ball(p.r * a[i] + s * h * u[i], p.ball_radius)
        parts.append(forearm.xml(n["forearm"], "forearm"))
        parts.append(_joint(n["joint"], "revolute", "base_link", n["forearm"], p.P[:, i], u[i], ACTUATOR_LIMITS))
        parts.append(_frame(n["A"], n["forearm"], p.r * a[i]))
        for j, s in enumerate(signs):
            b = bar_names(i + 1, j + 1)
            anchor = p.r * a[i] + s * h * u[i]
            parts.append(_frame(b["A"], n["forearm"], anchor))
            cross = _Body()
            cross.ball(np.zeros(3), p.ball_radius * 0.5, CROSS_MASS)
            parts.append(cross.xml(b["cross"], "joint"))
            parts.append(_joint(b["u1"], "revolute", n["forearm"], b["cross"], anchor, u[i], (-np.pi, np.pi)))
            bar = _Body()
            bar.rod(np.zeros(3), np.array([0.0, 0.0, -p.l]), BAR_RADIUS, RHO_CARBON, bar_inner)
            parts.append(bar.xml(b["bar"], "bar"))
            parts.append(_joint(b["u2"], "revolute", b["cross"], b["bar"], np.zeros(3), a[i], (-np.pi, np.pi)))
            parts.append(_frame(b["end"], b["bar"], np.array([0.0, 0.0, -p.l])))

    central = _Body()
    central.rod(p.DC[:, 0], p.DC[:, 1], PLATE_RADIUS, RHO_ALUMINIUM)
    central.rod(np.zeros(3), p.DC.mean(axis=1), PLATE_RADIUS, RHO_ALUMINIUM)
    central.ball(np.zeros(3), 1.5 * PLATE_RADIUS)
    parts.append(central.xml("central_bar", "plate"))
    parts.append(_joint("plate", "floating", "base_link", "central_bar", np.zeros(3)))
    parts.append(_frame("D", "central_bar", np.zeros(3)))
    bij = p.plate_ball_centres()
    for k in range(2):
        n = lateral_names(k + 1)
        lateral = _Body()
        for i in np.flatnonzero(LEG_LATERAL == k):
            lateral.rod(np.zeros(3), p.DB[:, i] - p.DC[:, k], PLATE_RADIUS, RHO_ALUMINIUM)
            lateral.rod(bij[i, 0] - p.DC[:, k], bij[i, 1] - p.DC[:, k], PLATE_RADIUS, RHO_ALUMINIUM)
            for j in range(2):
                lateral.ball(bij[i, j] - p.DC[:, k], p.ball_radius)
        parts.append(lateral.xml(n["link"], "plate"))
        parts.append(_joint(n["joint"], "revolute", "central_bar", n["link"], p.DC[:, k], np.array([0.0, 0.0, 1.0]),
                            (-np.pi, np.pi)))
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
                f'    <parent_origin xyz="0 0 {_num(-p.l)}"/>\n'
                f'    <child link="{lateral_names(k + 1)["link"]}"/>\n'
                f'    <child_origin xyz="{_vec(bij[i, j] - p.DC[:, k])}"/>\n'
                "  </constraint>"
            )

    materials = {"frame": "0.35 0.37 0.40 1", "forearm": "0.80 0.45 0.15 1", "bar": "0.15 0.15 0.17 1",
                 "joint": "0.6 0.6 0.6 1", "plate": "0.20 0.45 0.80 1"}
    header = [
        '<?xml version="1.0"?>',
        f"<!-- H4 parallel robot '{name}', written by h4pin.urdf.to_urdf: do not edit by hand. -->",
        f'<robot name="{name}">',
        *(f'  <material name="{m}"><color rgba="{c}"/></material>' for m, c in materials.items()),
    ]
    return "\n".join([*header, *parts, *closures, _parameters_xml(p), "</robot>", ""])


_LEG_FIELDS = ("P", "U", "DB")
_DIMENSIONS = ("r", "l", "half_width", "ball_radius")
_SPRINGS = ("kc", "E", "I", "G", "I0", "Sb", "Eb", "forearm_stressed_fraction")


def _parameters_xml(p: H4Params) -> str:
    out = [f'  <h4_parameters format="{FORMAT_VERSION}" units="SI">']
    for i in range(4):
        attrs = " ".join(f'{f}="{_vec(getattr(p, f)[:, i])}"' for f in _LEG_FIELDS)
        out.append(f'    <leg index="{i + 1}" lateral_bar="{LEG_LATERAL[i] + 1}" {attrs}/>')
    for k in range(2):
        out.append(f'    <lateral_bar index="{k + 1}" DC="{_vec(p.DC[:, k])}"/>')
    out.append("    <dimensions " + " ".join(f'{f}="{_num(getattr(p, f))}"' for f in _DIMENSIONS) + "/>")
    out.append("    <springs " + " ".join(f'{f}="{_num(getattr(p, f))}"' for f in _SPRINGS) + "/>")
    out.append("  </h4_parameters>")
    return "\n".join(out)


def _parse(text: str, where: str) -> ET.Element:
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise MalformedURDFError(f"{where}: not well-formed XML ({exc})") from None
    if root.tag != "robot":
        raise MalformedURDFError(f"{where}: the root element is <{root.tag}>, not <robot>")
    return root


def _attr(elem: ET.Element | None, key: str, where: str, what: str) -> str:
    if elem is None or elem.get(key) is None:
        raise MalformedURDFError(f"{where}: {what} is missing attribute '{key}'")
    return elem.get(key)  # type: ignore[return-value]


def _floats(text: str, n: int, where: str, what: str) -> np.ndarray:
    try:
        v = np.array([float(t) for t in text.split()])
    except ValueError:
        raise MalformedURDFError(f"{where}: {what} = {text!r} is not a list of numbers") from None
    if v.shape != (n,):
        raise MalformedURDFError(f"{where}: {what} = {text!r} must have {n} numbers")
    return v


def params_from_urdf(text: str, where: str = "URDF") -> H4Params:
    """Read the :class:`H4Params` stored in a URDF written by :func:`to_urdf`, and check it.

    Args:
        text: URDF XML text.
        where: Name of the source used in error messages (e.g. the file path).

    Raises:
        MalformedURDFError: the ``<h4_parameters>`` element or one of its data is missing, a
            closure is missing or names an unknown link, or the tree disagrees with the data.
        h4pin.ParameterError: the stored data are not valid parameters.
    """
    root = _parse(text, where)
    hp = root.find("h4_parameters")
    if hp is None:
        raise MalformedURDFError(f"{where}: no <h4_parameters> element (spring data and geometry of the H4)")
    legs = {e.get("index"): e for e in hp.findall("leg")}
    laterals = {e.get("index"): e for e in hp.findall("lateral_bar")}
    arrays = {f: np.zeros((3, 4)) for f in _LEG_FIELDS}
    for i in range(4):
        leg = legs.get(str(i + 1))
        if leg is None:
            raise MalformedURDFError(f"{where}: <h4_parameters> has no <leg index=\"{i + 1}\">")
        for f in _LEG_FIELDS:
            arrays[f][:, i] = _floats(_attr(leg, f, where, f"<leg index=\"{i + 1}\">"), 3, where, f"leg {i + 1} {f}")
    dc = np.zeros((3, 2))
    for k in range(2):
        dc[:, k] = _floats(_attr(laterals.get(str(k + 1)), "DC", where, f"<lateral_bar index=\"{k + 1}\">"), 3,
                           where, f"lateral bar {k + 1} DC")
    scalars: dict[str, float] = {}
    for tag, fields in (("dimensions", _DIMENSIONS), ("springs", _SPRINGS)):
        elem = hp.find(tag)
        if elem is None:
            raise MalformedURDFError(f"{where}: <h4_parameters> has no <{tag}> element")
        for f in fields:
            label = "spring datum" if tag == "springs" else "dimension"
            scalars[f] = float(_floats(_attr(elem, f, where, f"{label} <{tag}>"), 1, where, f)[0])
    params = H4Params(**arrays, DC=dc, **scalars)
    check_tree(root, params, where)
    return params


def _origin(elem: ET.Element, where: str, what: str) -> np.ndarray:
    o = elem.find("origin")
    if o is None:
        return np.zeros(3)
    if any(abs(x) > 0 for x in _floats(o.get("rpy", "0 0 0"), 3, where, f"{what} rpy")):
        raise MalformedURDFError(f"{where}: {what} has a non-zero rpy; h4pin writes world-aligned origins")
    return _floats(o.get("xyz", "0 0 0"), 3, where, f"{what} xyz")


def check_tree(root: ET.Element, p: H4Params, where: str = "URDF", tol: float = 1e-9) -> None:
    """Check that the kinematic tree and closures of ``root`` agree with the parameters ``p``."""
    links = {e.get("name") for e in root.findall("link")}
    joints = {e.get("name"): e for e in root.findall("joint")}

    def joint(name: str, kind: str) -> ET.Element:
        j = joints.get(name)
        if j is None:
            raise MalformedURDFError(f"{where}: joint '{name}' is missing")
        if j.get("type") != kind:
            raise MalformedURDFError(f"{where}: joint '{name}' has type '{j.get('type')}', expected '{kind}'")
        return j

    def agree(name: str, got: np.ndarray, want: np.ndarray, what: str) -> None:
        if not np.allclose(got, want, atol=tol, rtol=0):
            raise MalformedURDFError(
                f"{where}: {what} of '{name}' is {got.tolist()}, <h4_parameters> says {want.tolist()}")

    for i in range(4):
        n = leg_names(i + 1)
        j = joint(n["joint"], "revolute")
        agree(n["joint"], _origin(j, where, n["joint"]), p.P[:, i], "origin")
        axis = _floats(_attr(j.find("axis"), "xyz", where, f"joint '{n['joint']}' <axis>"), 3, where, "axis")
        agree(n["joint"], axis, p.U[:, i], "axis")
        for jj, s in enumerate((1.0, -1.0)):
            b = bar_names(i + 1, jj + 1)
            agree(b["u1"], _origin(joint(b["u1"], "revolute"), where, b["u1"]),
                  p.r * p.forearm_dirs[:, i] + s * p.half_width * p.U[:, i], "origin (A_ij in the forearm frame)")
            joint(b["u2"], "revolute")
    joint("plate", "floating")
    for k in range(2):
        n = lateral_names(k + 1)
        agree(n["joint"], _origin(joint(n["joint"], "revolute"), where, n["joint"]), p.DC[:, k], "origin")

    closures = {e.get("name"): e for e in root.findall("constraint")}
    bij = p.plate_ball_centres()
    for i in range(4):
        k = LEG_LATERAL[i]
        for jj in range(2):
            b = bar_names(i + 1, jj + 1)
            c = closures.get(b["closure"])
            if c is None:
                raise MalformedURDFError(
                    f"{where}: loop closure '{b['closure']}' (bar {i + 1}{jj + 1} on the plate) is missing")
            for side in ("parent", "child"):
                link = _attr(c.find(side), "link", where, f"<{side}> of closure '{b['closure']}'")
                if link not in links:
                    raise MalformedURDFError(f"{where}: closure '{b['closure']}' names unknown link '{link}'")
            want_parent, want_child = b["bar"], lateral_names(k + 1)["link"]
            if (c.find("parent").get("link"), c.find("child").get("link")) != (want_parent, want_child):  # type: ignore[union-attr]
                raise MalformedURDFError(
                    f"{where}: closure '{b['closure']}' must join '{want_parent}' to '{want_child}'")
            po, co = (_floats(_attr(c.find(f"{side}_origin"), "xyz", where, f"<{side}_origin> of '{b['closure']}'"),
                              3, where, "xyz") for side in ("parent", "child"))
            agree(b["closure"], po, np.array([0.0, 0.0, -p.l]), "parent_origin")
            agree(b["closure"], co, bij[i, jj] - p.DC[:, k], "child_origin")


def closures_from_urdf(text: str, where: str = "URDF") -> list[tuple[str, str, np.ndarray, str, np.ndarray]]:
    """The ``<constraint>`` elements as (name, parent link, parent xyz, child link, child xyz)."""
    root = _parse(text, where)
    out = []
    for c in root.findall("constraint"):
        name = _attr(c, "name", where, "<constraint>")
        parts = []
        for side in ("parent", "child"):
            link = _attr(c.find(side), "link", where, f"<{side}> of closure '{name}'")
            origin = _attr(c.find(f"{side}_origin"), "xyz", where, f"<{side}_origin> of '{name}'")
            xyz = _floats(origin, 3, where, "xyz")
            parts += [link, xyz]
        out.append((name, *parts))
    return out


def write_urdf(params: H4Params, path: str | Path, name: str | None = None) -> Path:
    """Write ``to_urdf(params)`` to ``path`` atomically (no half-written file on failure)."""
    path = Path(path)
    text = to_urdf(params, name or path.stem)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    tmp.replace(path)
    return path
