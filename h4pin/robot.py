# SPDX-License-Identifier: Apache-2.0
"""The H4 as a Pinocchio model with loop closures: :func:`load` and :class:`H4`.

``load("prototype")`` returns an :class:`H4`: an immutable value holding what
:func:`h4pin.description.reader.read` read from the URDF (the shared ``pin.Model``, its geometry
models, the eight closures, :attr:`H4.geometry`, :attr:`H4.elements`). Its methods are shorthands
for the free functions of :mod:`h4pin.kinematics.pinocchio` and :mod:`h4pin.kinematics.closed_form`,
which work in the calling thread's own ``pin.Data`` (:attr:`H4.data`) unless given one: one robot
can be shared by any number of threads.

Velocity split: the 4 actuated joints ``v_act`` and the 24 passive ones ``v_pas`` (16 bar
revolutes, 6 plate free-flyer, 2 lateral revolutes). The 24 closure equations
``Jc_a v_a + Jc_p v_p = 0`` have a square 24x24 passive block away from singularities, so the
passive velocities follow from the actuated ones: ``v_p = -Jc_p^-1 Jc_a v_a``.

Collisions: :attr:`H4.collision_model` holds every pair of collision geometries except those of
:func:`disabled_collisions` (links joined by a joint, and links that always touch at a joint
centre), the same pairs as example-robot-data's loader gives from the shipped SRDF. It is built on
first use. :meth:`H4.point_constraints` gives the closures as Pinocchio 4's bilateral point
constraints (``pin.PointAnchorConstraintModel``); :attr:`H4.constraint_models` keeps the legacy
``RigidConstraintModel`` on every supported Pinocchio.
"""

from __future__ import annotations

import os
import threading
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple
from xml.sax.saxutils import quoteattr

import numpy as np
import pinocchio as pin

from h4pin import limits
from h4pin.description.elements import Elements, kinds
from h4pin.description.geometry import BAR_CLEARANCE, params_from_geometry
from h4pin.description.params import VARIANTS, H4Params
from h4pin.description.reader import read
from h4pin.description.urdf import decode, parse, to_urdf
from h4pin.errors import H4Error, MalformedURDFError, ParameterError, URDFNotFoundError
from h4pin.inputs import check_real, describe, real_array, short
from h4pin.kinematics import closed_form as cf
from h4pin.kinematics import pinocchio as kin
from h4pin.kinematics.closed_form import PlateState


def urdf_dir() -> Path:
    """Folder of the shipped URDF files (inside the installed package, or the repo's ``urdf/``)."""
    packaged = Path(str(resources.files("h4pin"))) / "urdf"
    if packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parent.parent / "urdf"


def variant_path(name: str) -> Path:
    """Path of the shipped URDF of variant ``name`` (``urdf/h4_<name>.urdf``)."""
    return urdf_dir() / f"h4_{name}.urdf"


class DisabledCollision(NamedTuple):
    """A pair of links whose collision geometries are never checked against each other, with the
    SRDF's reason (``<disable_collisions link1 link2 reason>``, MoveIt's vocabulary)."""

    link1: str
    link2: str
    reason: str


def disabled_collisions(urdf_text: str, source: str = "URDF") -> tuple[DisabledCollision, ...]:
    """The link pairs of an H4 URDF whose collisions are not checked, in file order.

    * ``"Adjacent"``: links joined by a URDF joint (not a floating one: the plate is not joined to
      the base), looking through links without collision geometry (frames such as ``A_11``), as
      MoveIt's setup assistant does;
    * ``"Always"``: links that touch at a joint centre in every configuration: the two ends of a
      universal joint (two revolutes through one point, the child joint at the origin of the link
      between them: forearm_i and bar_ij around the cross ``bar_ij_cross``), and the two links of
      each closure (``<constraint>``, the ball joint of bar ij on its lateral bar).

    This is what :func:`h4pin.io.erd.srdf` writes into the shipped SRDFs; every other pair of
    geometries is checked. ``tests/test_erd.py`` checks that every disabled pair of the shipped
    variants touches and that no checked pair does, at ``q0`` and at sampled poses.

    Raises:
        MalformedURDFError: the text is not XML.
    """
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as exc:
        raise MalformedURDFError(f"{source}: not well-formed XML ({exc})") from None
    links = [link.get("name", "") for link in root.findall("link")]
    solid = {link.get("name") for link in root.findall("link") if link.find("collision") is not None}
    up: dict[str, tuple[str, ET.Element]] = {}  # child link -> (parent link, joint)
    for joint in root.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if joint.get("type") != "floating" and parent is not None and child is not None:
            up[child.get("link", "")] = (parent.get("link", ""), joint)

    def solid_parent(link: str) -> str | None:
        while link in up:
            link = up[link][0]
            if link in solid:
                return link
        return None

    out: dict[frozenset[str], DisabledCollision] = {}

    def add(a: str | None, b: str, reason: str) -> None:
        if a is not None and a != b and frozenset((a, b)) not in out:
            out[frozenset((a, b))] = DisabledCollision(a, b, reason)

    for link in (name for name in links if name in solid):
        add(solid_parent(link), link, "Adjacent")
    for link in (name for name in links if name in solid):
        parent, joint = up.get(link, ("", None))
        origin = joint.find("origin") if joint is not None else None
        at_origin = origin is None or all(float(v) == 0 for v in origin.get("xyz", "0 0 0").split())
        if joint is not None and joint.get("type") != "fixed" and parent in solid and at_origin:
            add(solid_parent(parent), link, "Always")
    for closure in parse(urdf_text, source).closures:
        if closure.parent in solid and closure.child in solid:
            add(closure.parent, closure.child, "Always")
    return tuple(out.values())


def disable_collisions_xml(pairs: tuple[DisabledCollision, ...], indent: str = "  ") -> list[str]:
    """The SRDF lines ``<disable_collisions link1=... link2=... reason=.../>`` of ``pairs``."""
    return [f"{indent}<disable_collisions link1={quoteattr(p.link1)} link2={quoteattr(p.link2)} "
            f"reason={quoteattr(p.reason)}/>" for p in pairs]


def load(source: str | bytes | Path | H4Params = "prototype", *, springs: dict[str, Any] | None = None,
         elements: Elements | dict[str, Any] | None = None, bar_clearance: float = BAR_CLEARANCE) -> H4:
    """Load an H4: a variant name, a path to a URDF file, the URDF's text, or an :class:`H4Params`.

    Args:
        source: ``"prototype"`` (default), ``"symmetric"``, ``"toleranced"``, ``"measured_match"`` (see
            :data:`h4pin.VARIANTS`), a path to any H4 URDF (an existing file is always taken as
            a path), the URDF's XML text itself (a ``str`` or ``bytes`` whose first character
            after white space is ``<``, as Pinocchio's ``buildModelFromXML`` takes; its
            :attr:`H4.source` is ``"URDF text"``), or parameters (the URDF is then generated in
            memory).
        springs: Spring data given or overridden at load, by H4Params field name: ``kc``, ``E``,
            ``I``, ``G``, ``I0``, ``forearm_stressed_fraction`` (a scalar or 4 values, one per
            leg), ``Sb``, ``Eb`` (a scalar or 8 values, one per bar).
        elements: The optional compliant elements (:class:`h4pin.Elements`, or a dict of its
            fields), replacing those of the URDF (default: the URDF's own).
        bar_clearance: m, the smallest distance allowed between the axes of bars of two legs.

    Raises:
        ParameterError: unknown variant name (the message lists them), a ``source`` of another
            type, bad ``springs``, ``elements`` or ``bar_clearance`` (each named, with what it got);
            :class:`h4pin.limits.ImplausibleValueError` (a ParameterError) for spring data outside
            :data:`h4pin.limits.SPRING_RANGES`, given here or in the URDF (a ``kc`` of 1e-300).
        URDFNotFoundError: the path does not exist (or cannot be read).
        MalformedURDFError: the file or text does not describe an H4 (the message names the element).
    """
    # The door (issue 30): the options' types before any reading (a bad one costs no URDF parse).
    springs = _as_springs(springs)
    elements = None if elements is None else _as_elements(elements)
    bar_clearance = check_real(bar_clearance, "bar_clearance", minimum=0.0, unit="m")
    options = {"springs": springs, "elements": elements, "bar_clearance": bar_clearance}
    if isinstance(source, H4Params):
        return H4(to_urdf(source), "<H4Params>", **options)
    if isinstance(source, (bytes, bytearray, memoryview)):
        data = bytes(source)
        if data.lstrip(_XML_SPACE.encode()).startswith((b"<", b"\xef\xbb\xbf")):  # XML text (or a UTF-8 BOM)
            return H4(_xml_text(decode(data, URDF_TEXT)), URDF_TEXT, **options)
        source = os.fsdecode(data)  # a path or a variant name
    elif isinstance(source, str) and source.lstrip(_XML_START).startswith("<"):
        return H4(_xml_text(source), URDF_TEXT, **options)
    if not isinstance(source, (str, os.PathLike)):
        raise ParameterError(f"source must be a variant name, a path, the URDF's text or an H4Params, "
                             f"got {describe(source)}")
    try:
        text_source = source if isinstance(source, str) else os.fsdecode(os.fspath(source))
    except (TypeError, ValueError):  # a PathLike whose __fspath__ gives no path
        raise ParameterError(f"source: a path-like object without a path, got {describe(source)}") from None
    path = Path(text_source)
    try:
        found = path.is_file()
    except (OSError, ValueError):  # a name too long for a path, a NUL byte
        found = False
    if not found:
        if isinstance(source, str) and text_source in VARIANTS:
            path = variant_path(text_source)
        elif isinstance(source, os.PathLike) or text_source.endswith(".urdf") or "/" in text_source:
            where = text_source if len(text_source) <= 200 else short(text_source)
            raise URDFNotFoundError(f"no URDF file at {where}")
        else:
            raise ParameterError(f"unknown H4 variant {short(text_source)}; available: {', '.join(sorted(VARIANTS))} "
                                 "(or pass a path to a URDF, its text, or an H4Params)")
    try:
        data = path.read_bytes()
    except OSError as exc:  # permissions, a file gone since is_file
        raise URDFNotFoundError(f"cannot read the URDF file at {path}: {exc.strerror or exc}") from None
    return H4(decode(data, str(path)), str(path), **options)


#: :attr:`H4.source` of a robot loaded from the URDF's text (``load(text)``).
URDF_TEXT = "URDF text"
_XML_SPACE = " \t\r\n"
_XML_START = "\ufeff" + _XML_SPACE  # what may come before the first "<" of URDF text


def _xml_text(text: str) -> str:
    """URDF text as :func:`load` keeps it: without a leading byte-order mark or white space, which
    XML allows before the root but not before a declaration (Pinocchio's reader skips them too)."""
    return text.lstrip(_XML_START)


def _as_springs(springs: Any) -> dict[str, np.ndarray] | None:
    """``load(..., springs=)``: None or a dict of field name -> real number(s), the values as float
    arrays (the reader checks the names, sizes and values); else a :class:`ParameterError`."""
    if springs is None:
        return None
    if not isinstance(springs, Mapping):
        raise ParameterError(f"springs must be a dict of H4Params spring fields or None, got {describe(springs)}")
    out = {}
    for name, value in springs.items():
        if not isinstance(name, str):
            raise ParameterError(f"springs: a field name must be a str, got {describe(name)}")
        out[name] = real_array(value, f"springs[{name!r}]", ParameterError)
    return out


def _as_elements(elements: Elements | dict[str, Any]) -> Elements:
    if isinstance(elements, Elements):
        return elements
    if isinstance(elements, Mapping):
        for name in elements:
            if not isinstance(name, str):
                raise ParameterError(f"elements: a field name must be a str, got {describe(name)}")
        known = [k.name for k in kinds()]
        unknown = set(elements) - set(known)
        if unknown:
            raise ParameterError(f"elements: unknown field(s) {', '.join(sorted(unknown))}; known: {', '.join(known)}")
        try:
            return Elements(**elements)
        except ParameterError as exc:  # the field's own message, said to be of this argument
            raise ParameterError(f"elements: {exc}") from None
    raise ParameterError(f"elements must be an h4pin.Elements or a dict of its fields, got {describe(elements)}")


class H4:
    """An H4 robot, immutable once loaded: Pinocchio model, geometry models, closures, per-element
    constants and the optional elements' data.

    Attributes:
        geometry: :class:`h4pin.H4Geometry`, read from the model at load.
        elements: :class:`h4pin.Elements`, the data of the elements eq. 30 neglects (from the
            URDF, or ``load(..., elements=...)``); :func:`h4pin.compliance` includes them.
        model: the Pinocchio model (shared; never changed by h4pin).
        data: the calling thread's own ``pin.Data`` of :attr:`model` (each thread gets one).
        visual_model: Pinocchio's visual geometry model.
        collision_model: Pinocchio's collision geometry model with its collision pairs: all pairs
            minus :attr:`disabled_collisions` (made on first use; shared, do not change it).
        disabled_collisions: the link pairs not checked (:func:`disabled_collisions`).
        constraint_models: the 8 ``CONTACT_3D`` closures, bar ij at B_ij, in the order 11, 12,
            21, ..., 42 (index n = 2(i-1) + (j-1)); joint 1 is the bar's.
        frames: Frame ids by name.
        actuated_joint_names: the 4 actuated joints, leg order.
        v_act, v_pas: Velocity indices of the 4 actuators and of the passive joints.
        index: where the parts sit in the model (:class:`h4pin.description.reader.Index`).
        q0: (nq,) the assembled configuration with every actuator at 45 deg (the paper's pose),
            also ``model.referenceConfigurations["q0"]`` (Pinocchio's convention); None if the
            robot does not assemble there.
        urdf: The URDF text; source: where it came from.

    Copies and pickles: an H4 travels as what defines it, not as its Pinocchio objects (which
    neither pickle nor deep-copy) or its per-thread data: :meth:`__reduce__` gives
    :func:`_rebuild` with the URDF text, the source name, the ``springs`` override of the load
    (as float arrays), the ``bar_clearance`` and the current :attr:`elements` (so a robot of
    :meth:`with_elements` or ``load(..., elements=...)`` keeps them). ``pickle`` (a process pool,
    a Dask worker) and ``copy.deepcopy`` both rebuild the robot from these (some 20 ms): a new
    model with the same geometry, springs and elements, bit-identical numbers, and new per-thread
    data on the other side. ``copy.copy`` returns the robot itself: it is immutable, and sharing
    one between threads is already safe.
    """

    def __init__(self, urdf_text: str, source: str = "URDF", *, springs: dict[str, Any] | None = None,
                 elements: Elements | dict[str, Any] | None = None, bar_clearance: float = BAR_CLEARANCE):
        desc = read(urdf_text, source, springs, bar_clearance)
        # Spring data within h4pin.limits.SPRING_RANGES (a kc of 1e-300 is a typo, not a robot).
        limits.check_springs(desc.geometry.springs, "springs" if springs else source)
        if elements is not None:
            desc = desc._replace(elements=_as_elements(elements))
        # What rebuilds this robot elsewhere (__reduce__): the override as read accepted it, as
        # plain read-only float arrays (a later change to the caller's arrays does not travel).
        override = {name: np.array(value, dtype=float) for name, value in (springs or {}).items()}
        for value in override.values():
            value.setflags(write=False)
        values = dict(desc._asdict(), urdf=urdf_text, source=source, _local=threading.local(),
                      _lazy={}, _lazy_lock=threading.RLock(), _springs_override=override,
                      _bar_clearance=float(bar_clearance))
        values["_collision_geometry"] = values.pop("collision_model")  # pairs added on first use
        for name, value in values.items():
            object.__setattr__(self, name, value)
        object.__setattr__(self, "q0", self._reference_configuration())

    def _reference_configuration(self) -> np.ndarray | None:
        """The assembled configuration with every actuator at 45 deg (the paper's pose), stored as
        Pinocchio's ``model.referenceConfigurations["q0"]`` (read-only here); None for a robot that
        does not assemble there."""
        try:
            q0 = kin.configuration(self, cf.centre_pose(self), check=False)
        except H4Error:
            return None
        self.model.referenceConfigurations["q0"] = q0  # the model is not shared yet
        q0 = q0.copy()
        q0.setflags(write=False)
        return q0

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"an H4 is immutable once loaded (cannot set {name!r}); load another one")

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        """Pickle and ``copy.deepcopy`` as :func:`_rebuild` of what defines this robot (class
        docstring): its URDF text, source, springs override, bar clearance and elements."""
        springs = dict(self._springs_override) or None
        return _rebuild, (self.urdf, self.source, springs, self.elements, self._bar_clearance)

    def __copy__(self) -> H4:
        """This robot itself: an H4 is immutable (``copy.deepcopy`` rebuilds a new one)."""
        return self

    @property
    def data(self) -> pin.Data:
        """The calling thread's own ``pin.Data`` of :attr:`model` (made on first use)."""
        d = getattr(self._local, "data", None)
        if d is None:
            d = self.model.createData()
            self._local.data = d
        return d

    @property
    def constraint_datas(self) -> Any:
        """The calling thread's own data of the 8 closures (``pin.StdVec_RigidConstraintData``)."""
        d = getattr(self._local, "constraint_datas", None)
        if d is None:
            d = pin.StdVec_RigidConstraintData()
            for cm in self.constraint_models:
                d.append(cm.createData())
            self._local.constraint_datas = d
        return d

    @property
    def disabled_collisions(self) -> tuple[DisabledCollision, ...]:
        """The link pairs whose collisions are not checked (:func:`disabled_collisions` of the URDF)."""
        return self._cached("disabled_collisions", lambda: disabled_collisions(self.urdf, self.source))

    @property
    def collision_model(self) -> pin.GeometryModel:
        """Pinocchio's collision model with its pairs: every pair of geometries of different joints
        (``addAllCollisionPairs``) minus those of :attr:`disabled_collisions`
        (``removeCollisionPairsFromXML``), as example-robot-data's loader does with the SRDF.
        Made on first use (about 2 ms) and shared: make a ``createData()`` per thread."""

        def build() -> pin.GeometryModel:
            geometry = self._collision_geometry
            geometry.addAllCollisionPairs()
            srdf = "\n".join(['<robot name="h4">', *disable_collisions_xml(self.disabled_collisions), "</robot>"])
            pin.removeCollisionPairsFromXML(self.model, geometry, srdf, False)
            return geometry

        return self._cached("collision_model", build)

    def _cached(self, key: str, make: Any) -> Any:
        """``make()`` once per robot (thread-safe), shared by every thread."""
        value = self._lazy.get(key)
        if value is None:
            with self._lazy_lock:
                value = self._lazy.get(key)
                if value is None:
                    value = self._lazy[key] = make()
        return value

    def point_constraints(self) -> Any:
        """The 8 closures as Pinocchio 4's bilateral point constraints: a new
        ``pin.StdVec_ConstraintModel`` of ``pin.PointAnchorConstraintModel`` (same joints, placements
        and names as :attr:`constraint_models`, same order), for Pinocchio 4's constraint algorithms
        (``getConstraintsJacobian``, the ADMM and PGS solvers). Their Jacobian is the negative of
        the legacy ``CONTACT_3D`` one (the residual is measured from the other end), so their forces
        are the negatives of the legacy ones; ``J^T lambda`` is the same.

        Raises:
            H4Error: Pinocchio 3.x, which has no point constraints (use :attr:`constraint_models`).
        """
        anchor = getattr(pin, "PointAnchorConstraintModel", None)
        if anchor is None or not hasattr(pin, "StdVec_ConstraintModel"):
            raise H4Error(f"point constraints need Pinocchio >= 4 (pin.PointAnchorConstraintModel); this is "
                          f"Pinocchio {pin.__version__}: use H4.constraint_models (RigidConstraintModel)")
        out = pin.StdVec_ConstraintModel()
        for cm in self.constraint_models:
            point = anchor(self.model, cm.joint1_id, cm.joint1_placement, cm.joint2_id, cm.joint2_placement)
            point.name = cm.name
            generic = pin.ConstraintModel(point)
            generic.name = cm.name  # the generic wrapper keeps its own name
            out.append(generic)
        return out

    @property
    def params(self) -> H4Params:
        """The nominal :class:`H4Params` of this robot, if its layout is one they describe.

        Raises:
            MalformedURDFError: the robot is not of that family (e.g. a toleranced robot)."""
        return params_from_geometry(self.geometry)

    def with_elements(self, elements: Elements | dict[str, Any]) -> H4:
        """The same robot with other optional elements (a new value; this one is unchanged)."""
        out = object.__new__(H4)
        for name, value in vars(self).items():
            object.__setattr__(out, name, value)
        object.__setattr__(out, "elements", _as_elements(elements))
        object.__setattr__(out, "_local", threading.local())  # the lazy collision model stays shared
        return out

    # Shorthands of the free functions (each documented there).
    def inverse_geometry(self, pose: np.ndarray, *, on_error: str = "raise", check: bool = True) -> np.ndarray:
        """:func:`h4pin.kinematics.closed_form.inverse_geometry` of this robot."""
        return cf.inverse_geometry(self.geometry, pose, on_error=on_error, check=check)

    def forward_geometry(self, q: np.ndarray, guess: np.ndarray | None = None) -> np.ndarray:
        """:func:`h4pin.kinematics.closed_form.forward_geometry` of this robot."""
        return cf.forward_geometry(self.geometry, q, guess)

    def jx_jq(self, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The paper's Jx and Jq of eq. 8 (closed form), ``Jx x_dot = Jq q_dot``."""
        x = cf.as_poses(pose)
        return cf.jx_jq(self.geometry, x, self.inverse_geometry(x))

    def state(self, pose: np.ndarray, *, check: bool = True) -> PlateState:
        """:func:`h4pin.kinematics.pinocchio.state`."""
        return kin.state(self, pose, check=check)

    def assemble(self, state: PlateState) -> np.ndarray:
        """:func:`h4pin.kinematics.pinocchio.assemble`."""
        return kin.assemble(self, state)

    def configuration(self, pose: np.ndarray, *, check: bool = True) -> np.ndarray:
        """:func:`h4pin.kinematics.pinocchio.configuration`."""
        return kin.configuration(self, pose, check=check)

    def kinematics(self, pose: np.ndarray, data: pin.Data | None = None) -> kin.Kinematics:
        """:func:`h4pin.kinematics.pinocchio.kinematics`."""
        return kin.kinematics(self, pose, data)

    def closure_residuals(self, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """:func:`h4pin.kinematics.pinocchio.closure_residuals`."""
        return kin.closure_residuals(self, q, data)

    def passive_map(self, q: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """:func:`h4pin.kinematics.pinocchio.passive_map`."""
        return kin.passive_map(self, q, data)

    def jacobian(self, pose: np.ndarray, data: pin.Data | None = None) -> np.ndarray:
        """:func:`h4pin.kinematics.pinocchio.jacobian`."""
        return kin.jacobian(self, pose, data)

    def frame_position(self, name: str, q: np.ndarray | None = None, data: pin.Data | None = None) -> np.ndarray:
        """:func:`h4pin.kinematics.pinocchio.frame_position`."""
        return kin.frame_position(self, name, q, data)

    def gravity_torques(self, pose: np.ndarray, gravity: np.ndarray | None = None,
                        data: pin.Data | None = None) -> np.ndarray:
        """:func:`h4pin.kinematics.pinocchio.gravity_torques`."""
        return kin.gravity_torques(self, pose, gravity, data)

    def potential_energy(self, pose: np.ndarray, data: pin.Data | None = None) -> float:
        """:func:`h4pin.kinematics.pinocchio.potential_energy`."""
        return kin.potential_energy(self, pose, data)

    def __repr__(self) -> str:
        return (f"H4(source={self.source!r}, nq={self.model.nq}, nv={self.model.nv}, "
                f"closures={len(self.constraint_models)})")


def _rebuild(urdf_text: str, source: str, springs: dict[str, np.ndarray] | None, elements: Elements,
             bar_clearance: float) -> H4:
    """An :class:`H4` made anew from what :meth:`H4.__reduce__` gives (unpickling, deep copies):
    the same geometry, springs and elements, new Pinocchio objects and per-thread data."""
    return H4(urdf_text, source, springs=springs, elements=elements, bar_clearance=bar_clearance)


__all__ = ["H4", "DisabledCollision", "disable_collisions_xml", "disabled_collisions", "load", "urdf_dir",
           "variant_path"]
