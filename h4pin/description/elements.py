# SPDX-License-Identifier: Apache-2.0
"""Data of the compliant elements that eq. 30 neglects (all off by default): the schema.

Elements (SI, one value per element; 0 switches a compliance off, ``inf`` a rigidity):

* ``revolute_radial`` (2,) m/N: each lateral-bar revolute joint C_k, in the plane normal to its
  axis v_k; ``revolute_axial`` (2,) m/N along v_k; ``revolute_tilt`` (2,) rad/(N.m) about the two
  axes normal to v_k;
* ``ball_radial`` (8,) m/N: each ball joint of bar ij (both ends), along the bar;
* ``central_EI``, ``central_GJ`` (2,) N.m^2: bending and torsion of the central bar's segment
  D-C_k; ``lateral_EI``, ``lateral_GJ`` (4,) N.m^2: the same for lateral bar k's arm C_k-B_i;
* ``shaft_tilt`` (4,) rad/(N.m): actuator i's shaft and bearings;
* ``base_translation`` (4,) m/N, ``base_rotation`` (4,) rad/(N.m): actuator i's mount on the base;
* ``forearm_out_EI`` (4,) N.m^2: forearm i's bending out of its plane (its tip moving along u_i),
  which eq. 30 leaves rigid (it bends the forearm about u_i only).

The data sit in the URDF next to their element (:mod:`h4pin.description.urdf`) and
:func:`h4pin.load` reads them into :attr:`H4.elements <h4pin.H4>`; :func:`h4pin.compliance` adds a
named term per element kind that is on (:mod:`h4pin.stiffness.elements`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from h4pin.errors import ParameterError

#: Sites: the wrench an element carries, from the pulls of the bars that load it: ``joint``, the
#: lateral bar k's bars about C_k (its revolute joint, and the central-bar segment D-C_k that
#: carries it); ``arm``, leg i's bars about B_i (lateral bar k's arm C_k-B_i); ``mount``, leg i's
#: bars about P_i (the actuator's shaft and mount); ``tip``, leg i's bars about A_i (the forearm's
#: tip); ``bar``, one bar's tension.
SITES = ("joint", "arm", "mount", "tip", "bar")
SITE_JOINT, SITE_ARM, SITE_MOUNT, SITE_TIP, SITE_BAR = range(len(SITES))
#: Forms of an element's compliance C (6 x 6 on the site's wrench [force, couple]) about its
#: axis e: isotropic, normal to e or along e, on the force or the couple; a straight
#: Euler-Bernoulli cantilever along e (bending, given as 1/EI; torsion, 1/GJ) of the element's
#: length, clamped at its root and loaded at the site's point; ``beam_bending_out``: the same
#: cantilever bending in one plane only, the one that holds e and the element's second axis n
#: (its ``normal``: a forearm's tip moving along u_i, turning about e x n). Each form is one
#: compiled term, :func:`h4pin.stiffness.pipeline.form_part` (its rank-one parts), which the
#: compliance and the natural frequencies share.
FORMS = ("force", "force_normal", "force_axial", "couple", "couple_normal", "couple_axial", "beam_bending",
         "beam_torsion", "beam_bending_out")
(FORM_FORCE, FORM_FORCE_NORMAL, FORM_FORCE_AXIAL, FORM_COUPLE, FORM_COUPLE_NORMAL, FORM_COUPLE_AXIAL,
 FORM_BEAM_BENDING, FORM_BEAM_TORSION, FORM_BEAM_BENDING_OUT) = range(len(FORMS))
#: Axes (from the element's root to its site's point, for the beams: their length): none
#: (isotropic forms), z (world), the revolute axis v_k of lateral bar k (z on the exact robots
#: of the compiled pipeline), u_i (actuator i), C_k - D (the central-bar segment), B_i - C_k
#: (lateral bar k's arm), A_i - P_i (forearm i), w_n (bar n).
AXES = ("none", "z", "revolute", "actuator", "central", "arm", "forearm", "bar")
AXIS_NONE, AXIS_Z, AXIS_REVOLUTE, AXIS_ACTUATOR, AXIS_CENTRAL, AXIS_ARM, AXIS_FOREARM, AXIS_BAR = range(len(AXES))
#: Where a kind's data sit in an H4 URDF (:mod:`h4pin.description.urdf`), one element each: the
#: lateral revolute joints k, the bar links n, the actuated joints i, the forearm links i, the
#: central bar's link (segment k: attribute ``<attr>_<k>``), the link of the lateral bar that holds
#: leg i (attribute ``<attr>_<i>``). Place -> (what it is, in a message; URDF element; whether one
#: URDF element holds several elements of a kind, each its own ``<attr>_<n>``).
PLACES = {"lateral_joint": ("lateral joint", "joint", False), "bar_link": ("bar link", "link", False),
          "actuated_joint": ("actuated joint", "joint", False), "forearm_link": ("forearm link", "link", False),
          "central_link": ("central bar link", "link", True), "lateral_link": ("lateral bar link", "link", True)}
#: The suffixes of the elastic model's virtual joints of one element, per form
#: (:func:`h4pin.elastic.h4.elastic_model`): a 6-D spring's three prismatic or revolute joints, two
#: normal to the axis, one along it, a beam's bending revolutes at its two Gauss points about the
#: two normals, its torsion revolute, its bending out of plane at the two Gauss points.
ELASTIC_SUFFIXES = {"force": ("_x", "_y", "_z"), "couple": ("_rx", "_ry", "_rz"), "force_normal": ("_a", "_b"),
                    "couple_normal": ("_a", "_b"), "force_axial": ("",), "couple_axial": ("",),
                    "beam_bending": ("_bend_1a", "_bend_1b", "_bend_2a", "_bend_2b"), "beam_torsion": ("_torsion",),
                    "beam_bending_out": ("_1", "_2")}


@dataclasses.dataclass(frozen=True)
class Kind:
    """One kind of compliant element: its schema row. Every path takes a kind from its row alone
    (no code names a kind): :class:`Elements` (its field, count, unit, plausible range), the URDF
    writer and reader (``urdf``, ``place``), the compiled compliance and natural frequencies and
    the numpy statics route (``site``, ``form``, ``axis``, ``normal``, ``series``: a table row,
    :func:`h4pin.stiffness.kernel.element_table`), the elastic model (``elastic``: its virtual
    joints, from the form). A kind made of existing sites, forms, axes and places is one row.

    Attributes:
        name: the :class:`Elements` field.
        count: elements of the kind (one value each).
        unit: of the value (SI).
        site, form, axis: where its load comes from and the shape of its compliance
            (:data:`SITES`, :data:`FORMS`, :data:`AXES`).
        rigidity: the value is a rigidity (N.m^2, ``inf`` is rigid, off) rather than a
            compliance (0 is off).
        series: identical elements in series per value (a bar's two ball joints: 2).
        normal: the second axis of ``beam_bending_out`` (:data:`AXES`).
        urdf: (tag, attribute) of its value in the URDF (``<tag attribute="..."/>``).
        place: the URDF element that holds it (:data:`PLACES`).
        elastic: name of element s's virtual joints in the elastic model, ``{s}`` its 1-based
            index (``{s}`` of a bar: ``ij``), followed by the form's suffixes
            (:data:`ELASTIC_SUFFIXES`; ``_A``, ``_B``... for elements in series).
        describe: element s in a message, ``{s}`` as in ``elastic``.
        plausible: (low, high) plausible range of a value that is on (default: by unit,
            :data:`h4pin.limits.ELEMENT_RANGES`).
    """

    name: str
    count: int
    unit: str
    site: str
    form: str
    axis: str = "none"
    rigidity: bool = False
    series: int = 1
    normal: str = "none"
    urdf: tuple[str, str] = ("", "")
    place: str = ""
    elastic: str = ""
    describe: str = ""
    plausible: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for value, table in ((self.site, SITES), (self.form, FORMS), (self.axis, AXES), (self.normal, AXES),
                             (self.place, tuple(PLACES))):
            if value not in table:
                raise ParameterError(f"Kind {self.name!r}: {value!r} is none of {table}")
        if self.plausible is None:
            from h4pin.limits import ELEMENT_RANGES

            object.__setattr__(self, "plausible", ELEMENT_RANGES[self.unit])

    @property
    def off(self) -> float:
        """The value that switches an element off: ``inf`` (a rigidity) or 0."""
        return np.inf if self.rigidity else 0.0

    def label(self, s: int) -> str:
        """Element s's ``{s}`` (1-based; ``ij`` for a bar)."""
        return f"{s // 2 + 1}{s % 2 + 1}" if self.site == "bar" else str(s + 1)

    def compliance(self, value: Any) -> np.ndarray:
        """The compliances (``count``,) of values of the kind, times ``series`` (0 where off)."""
        raw = np.broadcast_to(np.asarray(value, dtype=float), (self.count,))
        if self.rigidity:
            with np.errstate(divide="ignore"):
                raw = np.where(np.isinf(raw), 0.0, 1.0 / raw)
        return self.series * raw


_JOINT = {"site": "joint", "place": "lateral_joint", "describe": "revolute joint of lateral bar {s}"}
_LEG = {"place": "actuated_joint", "site": "mount"}
#: The element kinds, in the order of their terms.
KINDS = (
    Kind("revolute_radial", 2, "m/N", form="force_normal", axis="revolute", urdf=("h4_revolute", "radial"),
         elastic="lateral_{s}_radial", **_JOINT),
    Kind("revolute_axial", 2, "m/N", form="force_axial", axis="revolute", urdf=("h4_revolute", "axial"),
         elastic="lateral_{s}_axial", **_JOINT),
    Kind("revolute_tilt", 2, "rad/(N.m)", form="couple_normal", axis="revolute", urdf=("h4_revolute", "tilt"),
         elastic="lateral_{s}_tilt", **_JOINT),
    Kind("ball_radial", 8, "m/N", "bar", "force_axial", "bar", series=2, urdf=("h4_ball", "radial"), place="bar_link",
         elastic="bar_{s}_ball", describe="ball joints of bar {s}"),
    Kind("central_EI", 2, "N.m^2", "joint", "beam_bending", "central", rigidity=True, urdf=("h4_plate_bar", "EI"),
         place="central_link", elastic="central_{s}", describe="central-bar segment D-C_{s}"),
    Kind("central_GJ", 2, "N.m^2", "joint", "beam_torsion", "central", rigidity=True, urdf=("h4_plate_bar", "GJ"),
         place="central_link", elastic="central_{s}", describe="central-bar segment D-C_{s}"),
    Kind("lateral_EI", 4, "N.m^2", "arm", "beam_bending", "arm", rigidity=True, urdf=("h4_plate_bar", "EI"),
         place="lateral_link", elastic="arm_{s}", describe="lateral-bar arm to B_{s}"),
    Kind("lateral_GJ", 4, "N.m^2", "arm", "beam_torsion", "arm", rigidity=True, urdf=("h4_plate_bar", "GJ"),
         place="lateral_link", elastic="arm_{s}", describe="lateral-bar arm to B_{s}"),
    Kind("shaft_tilt", 4, "rad/(N.m)", form="couple_normal", axis="actuator", urdf=("h4_actuator", "shaft_tilt"),
         elastic="shaft_{s}_tilt", describe="actuator shaft of leg {s}", **_LEG),
    Kind("base_translation", 4, "m/N", form="force", urdf=("h4_base", "translation"), elastic="mount_{s}",
         describe="base mount of actuator {s}", **_LEG),
    Kind("base_rotation", 4, "rad/(N.m)", form="couple", urdf=("h4_base", "rotation"), elastic="mount_{s}",
         describe="base mount of actuator {s}", **_LEG),
    Kind("forearm_out_EI", 4, "N.m^2", "tip", "beam_bending_out", "forearm", rigidity=True, normal="actuator",
         urdf=("h4_forearm", "out_EI"), place="forearm_link", elastic="forearm_{s}_out", describe="forearm {s}"),
)
ELEMENTS = tuple(k.name for k in KINDS)
#: Number of elements of each kind: per lateral revolute joint or central-bar segment D-C_k (2),
#: per leg (4: lateral arm C_k-B_i, actuator shaft, base mount, forearm) or per bar (8).
COUNTS = {k.name: k.count for k in KINDS}
#: Kinds given as a stiffness (N.m^2): > 0, ``inf`` (the default) is rigid, i.e. off. The others
#: are compliances: >= 0, 0 (the default) is off.
RIGIDITIES = tuple(k.name for k in KINDS if k.rigidity)
UNITS = {k.name: k.unit for k in KINDS}


def kinds() -> tuple[Kind, ...]:
    """The schema's rows now (:data:`KINDS`, read at each call: a test may add a row)."""
    return KINDS


def kind(name: str) -> Kind:
    """The schema row of kind ``name``."""
    for k in kinds():
        if k.name == name:
            return k
    raise ParameterError(f"Elements: no element kind {name!r} (kinds: {', '.join(k.name for k in kinds())})")


def element_name(name: str, index: int) -> str:
    """Human name of element ``index`` of kind ``name`` (1-based joint, segment, leg or bar)."""
    k = kind(name)
    return k.describe.format(s=k.label(index)) if k.describe else f"{name} {k.label(index)}"


def is_on(name: str, value: np.ndarray) -> bool:
    """True when some element of kind ``name`` with data ``value`` is not rigid."""
    return bool(np.any(np.isfinite(value))) if kind(name).rigidity else bool(np.any(value))


def _checked(k: Kind, raw: Any, error: type[Exception], prefix: str, owners: list[str] | None) -> np.ndarray:
    """One kind's data as a read-only float array (:func:`check_elements`)."""
    from h4pin.inputs import describe, real_array  # h4pin.inputs imports nothing of h4pin.description
    from h4pin.limits import ImplausibleValueError

    name, n = k.name, k.count
    what = f"a real number or {n} of them ({k.unit})"
    if isinstance(raw, (list, tuple)) and any(isinstance(v, (bool, np.bool_)) for v in raw):
        raise error(f"{prefix}{name} must be {what} (not bools), got {describe(raw)}")
    arr = real_array(raw, f"{prefix}{name}", error, what)
    try:
        arr = np.broadcast_to(arr, (n,)).copy()
    except ValueError:
        raise error(f"{prefix}{name} must be {what}, got {describe(raw)}") from None
    bad = np.isnan(arr) | (arr <= 0.0) if k.rigidity else ~np.isfinite(arr) | (arr < 0.0)
    if np.any(bad):
        i = int(np.argmax(bad))
        owner = owners[i] if owners else element_name(name, i)
        rule = "> 0; inf switches it off" if k.rigidity else "finite and >= 0; 0 switches it off"
        raise error(f"{prefix}{owner}: {name} = {float(arr[i])!r} is not physical (must be {rule})")
    lo, hi = k.plausible
    odd = (arr != 0.0) & np.isfinite(arr) & ((arr < lo) | (arr > hi))
    if np.any(odd):
        i = int(np.argmax(odd))
        owner = owners[i] if owners else element_name(name, i)
        raise ImplausibleValueError(f"{prefix}{owner}: {name} = {float(arr[i]):g} {k.unit} is outside the "
                                    f"plausible range [{lo:g}, {hi:g}] {k.unit} ({k.off:g} switches it off; "
                                    "h4pin.limits.ELEMENT_RANGES)")
    arr.setflags(write=False)
    return arr


def check_elements(values: dict[str, Any], error: type[Exception] = ParameterError, where: str = "",
                   owners: dict[str, list[str]] | None = None) -> dict[str, np.ndarray]:
    """Element data as float arrays (scalars broadcast to each kind's count): compliances finite
    and >= 0, rigidities > 0 (``inf``: rigid), within the kind's plausible range when on;
    otherwise ``error`` naming the element (and ``owners[name][index]``). A value must be real
    numbers: bools (``True`` is not a compliance), text, ``None``, complex numbers and masked
    arrays are refused, naming the field."""
    prefix = f"{where}: " if where else ""
    return {k.name: _checked(k, values.get(k.name, k.off), error, prefix, owners[k.name] if owners else None)
            for k in kinds()}


@dataclasses.dataclass(frozen=True, eq=False, init=False)
class Elements:
    """Data of the neglected elements, SI, per element (all off by default).

    Each field accepts a scalar (every element of that kind) or one value per element:

    * ``revolute_radial``, ``revolute_axial`` (m/N), ``revolute_tilt`` (rad/(N.m)), (2,): the
      lateral bars' revolute joints k = 1, 2; ``ball_radial`` (8,) m/N: the ball joints of bars
      11, 12, ..., 42 (each bar's two ball joints have that compliance). 0: off.
    * ``central_EI``, ``central_GJ`` (2,) N.m^2: bending and torsion rigidity of the central bar's
      segment from D to C_k; ``lateral_EI``, ``lateral_GJ`` (4,) N.m^2: the same for the arm of a
      lateral bar from C_k to B_i (leg i). ``inf``: rigid (off).
    * ``shaft_tilt`` (4,) rad/(N.m): actuator i's shaft and bearings, the forearm root at P_i
      turning about the two axes normal to u_i. 0: off.
    * ``base_translation`` (4,) m/N and ``base_rotation`` (4,) rad/(N.m): actuator i's mount on
      the base, an isotropic 6-D spring at P_i. 0: off.
    * ``forearm_out_EI`` (4,) N.m^2: bending rigidity of forearm i out of its plane (about the
      normal e x u_i to the forearm axis e in the plane of the forearm's rotation), a cantilever of
      the whole forearm P_i-A_i clamped at P_i, its tip A_i moving along u_i. A round tube has
      the forearm's E I about both normals. ``inf``: rigid (off), the paper's model.
    """

    revolute_radial: Any = 0.0
    revolute_axial: Any = 0.0
    revolute_tilt: Any = 0.0
    ball_radial: Any = 0.0
    central_EI: Any = np.inf
    central_GJ: Any = np.inf
    lateral_EI: Any = np.inf
    lateral_GJ: Any = np.inf
    shaft_tilt: Any = 0.0
    base_translation: Any = 0.0
    base_rotation: Any = 0.0
    forearm_out_EI: Any = np.inf

    def __init__(self, *args: Any, **values: Any) -> None:
        if args:
            raise ParameterError(f"Elements takes its values by name (Elements(ball_radial=2e-8), kinds: "
                                 f"{', '.join(k.name for k in kinds())}), got {len(args)} positional argument(s)")
        for name in values:
            kind(name)  # an unknown kind is refused, naming the kinds
        for k in kinds():
            object.__setattr__(self, k.name, values.get(k.name, k.off))
        self.__post_init__()

    def __reduce__(self) -> tuple[Any, ...]:
        """Unpickled (and deep-copied) through the constructor: checked like new ones."""
        return (_elements, ({k.name: np.array(getattr(self, k.name)) for k in kinds()},))

    def __post_init__(self) -> None:
        checked = check_elements({k.name: getattr(self, k.name) for k in kinds()})
        for name, value in checked.items():
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_on", frozenset(n for n, v in checked.items() if is_on(n, v)))

    def on(self, name: str) -> bool:
        """True when some element of kind ``name`` is switched on."""
        return name in self._on

    @property
    def off(self) -> bool:
        """True when every element is switched off (eq. 30 as it is)."""
        return not self._on

    def allclose(self, other: Elements, rtol: float = 1e-15) -> bool:
        """Every element equal to ``other``'s within ``rtol`` (relative; ``inf`` equals ``inf``)."""
        return all(np.allclose(getattr(self, k.name), getattr(other, k.name), rtol=rtol, atol=0.0) for k in kinds())

    def kinds_on(self) -> tuple[Kind, ...]:
        """The schema rows of the kinds that are on, in the order of their terms."""
        return tuple(k for k in kinds() if k.name in self._on)


def _elements(values: dict[str, Any]) -> Elements:
    """:class:`Elements` from its fields (the pickle path)."""
    return Elements(**values)


#: Plate rods of the generated URDF: solid aluminium rounds of radius 8 mm (E = 70 GPa,
#: G = 26 GPa): EI = E pi r^4 / 4, GJ = G pi r^4 / 2.
_ROD_I = np.pi * 8e-3**4 / 4.0
#: Orders of magnitude for a report, not data of the prototype: a pair of deep-groove bearings
#: (radial/axial ~1e8 N/m, tilt ~2e4 N.m/rad with 20 mm between them), a 10 mm ball joint ~5e7 N/m;
#: the plate's bars as the URDF's 8 mm aluminium rods (EI 225 N.m^2, GJ 167 N.m^2); the actuator
#: shaft on two bearings of ~1e8 N/m 30 mm apart (k s^2 / 2 = 4.5e4 N.m/rad: 2e-5 rad/(N.m)); a
#: motor bolted to an aluminium frame through a ~10 mm bracket (1e8 N/m, 1e5 N.m/rad); the
#: forearms out of plane with the paper's in-plane E I (70 GPa x 1.6e4 mm^4 = 1 120 N.m^2).
ILLUSTRATIVE = Elements(revolute_radial=1e-8, revolute_axial=1e-8, revolute_tilt=5e-5, ball_radial=2e-8,
                        central_EI=70e9 * _ROD_I, central_GJ=26e9 * 2 * _ROD_I, lateral_EI=70e9 * _ROD_I,
                        lateral_GJ=26e9 * 2 * _ROD_I, shaft_tilt=2e-5, base_translation=1e-8, base_rotation=1e-5,
                        forearm_out_EI=70e9 * 1.6e-8)


__all__ = ["AXES", "COUNTS", "ELASTIC_SUFFIXES", "ELEMENTS", "FORMS", "ILLUSTRATIVE", "KINDS", "PLACES", "RIGIDITIES",
           "SITES", "UNITS", "Elements", "Kind", "check_elements", "element_name", "is_on", "kind", "kinds"]
