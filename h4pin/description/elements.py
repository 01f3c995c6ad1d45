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
#: cantilever bending in one plane only, the one that holds e and the actuator axis u_i (a
#: forearm's tip moving along u_i, turning about e x u_i).
FORMS = ("force", "force_normal", "force_axial", "couple", "couple_normal", "couple_axial", "beam_bending",
         "beam_torsion", "beam_bending_out")
(FORM_FORCE, FORM_FORCE_NORMAL, FORM_FORCE_AXIAL, FORM_COUPLE, FORM_COUPLE_NORMAL, FORM_COUPLE_AXIAL,
 FORM_BEAM_BENDING, FORM_BEAM_TORSION, FORM_BEAM_BENDING_OUT) = range(len(FORMS))
#: Axes: none (isotropic forms), z (the lateral revolutes of an exact robot), u_i (actuator i),
#: C_k - D (the central-bar segment), B_i - C_k (lateral bar k's arm), A_i - P_i (forearm i),
#: w_n (bar n).
AXES = ("none", "z", "actuator", "central", "arm", "forearm", "bar")
AXIS_NONE, AXIS_Z, AXIS_ACTUATOR, AXIS_CENTRAL, AXIS_ARM, AXIS_FOREARM, AXIS_BAR = range(len(AXES))


@dataclasses.dataclass(frozen=True)
class Kind:
    """One kind of compliant element: the schema row from which the compiled compliance and the
    compiled natural frequencies take it (:func:`h4pin.stiffness.kernel.element_table`); a kind
    made of an existing site, form and axis needs no compiled code. (The URDF tags, the numpy
    statics route and the elastic model's virtual joints are written per kind.)

    Attributes:
        name: the :class:`Elements` field.
        count: elements of the kind (one value each).
        unit: of the value (SI).
        site, form, axis: where its load comes from and the shape of its compliance
            (:data:`SITES`, :data:`FORMS`, :data:`AXES`).
        rigidity: the value is a rigidity (N.m^2, ``inf`` is rigid, off) rather than a
            compliance (0 is off).
        series: identical elements in series per value (a bar's two ball joints: 2).
    """

    name: str
    count: int
    unit: str
    site: str
    form: str
    axis: str = "none"
    rigidity: bool = False
    series: float = 1.0


#: The element kinds, in the order of their terms.
KINDS = (
    Kind("revolute_radial", 2, "m/N", "joint", "force_normal", "z"),
    Kind("revolute_axial", 2, "m/N", "joint", "force_axial", "z"),
    Kind("revolute_tilt", 2, "rad/(N.m)", "joint", "couple_normal", "z"),
    Kind("ball_radial", 8, "m/N", "bar", "force_axial", "bar", series=2.0),
    Kind("central_EI", 2, "N.m^2", "joint", "beam_bending", "central", rigidity=True),
    Kind("central_GJ", 2, "N.m^2", "joint", "beam_torsion", "central", rigidity=True),
    Kind("lateral_EI", 4, "N.m^2", "arm", "beam_bending", "arm", rigidity=True),
    Kind("lateral_GJ", 4, "N.m^2", "arm", "beam_torsion", "arm", rigidity=True),
    Kind("shaft_tilt", 4, "rad/(N.m)", "mount", "couple_normal", "actuator"),
    Kind("base_translation", 4, "m/N", "mount", "force"),
    Kind("base_rotation", 4, "rad/(N.m)", "mount", "couple"),
    Kind("forearm_out_EI", 4, "N.m^2", "tip", "beam_bending_out", "forearm", rigidity=True),
)
ELEMENTS = tuple(k.name for k in KINDS)
#: Number of elements of each kind: per lateral revolute joint or central-bar segment D-C_k (2),
#: per leg (4: lateral arm C_k-B_i, actuator shaft, base mount, forearm) or per bar (8).
COUNTS = {k.name: k.count for k in KINDS}
#: Kinds given as a stiffness (N.m^2): > 0, ``inf`` (the default) is rigid, i.e. off. The others
#: are compliances: >= 0, 0 (the default) is off.
RIGIDITIES = tuple(k.name for k in KINDS if k.rigidity)
UNITS = {k.name: k.unit for k in KINDS}


def element_name(name: str, index: int) -> str:
    """Human name of element ``index`` of kind ``name`` (1-based joint, segment, leg or bar)."""
    if name.startswith("revolute"):
        return f"revolute joint of lateral bar {index + 1}"
    if name.startswith("central"):
        return f"central-bar segment D-C_{index + 1}"
    if name.startswith("lateral"):
        return f"lateral-bar arm to B_{index + 1}"
    if name == "shaft_tilt":
        return f"actuator shaft of leg {index + 1}"
    if name.startswith("base"):
        return f"base mount of actuator {index + 1}"
    if name.startswith("forearm"):
        return f"forearm {index + 1}"
    return f"ball joints of bar {index // 2 + 1}{index % 2 + 1}"


def is_on(name: str, value: np.ndarray) -> bool:
    """True when some element of kind ``name`` with data ``value`` is not rigid."""
    return bool(np.any(np.isfinite(value))) if name in RIGIDITIES else bool(np.any(value))


def check_elements(values: dict[str, Any], error: type[Exception] = ParameterError, where: str = "",
                   owners: dict[str, list[str]] | None = None) -> dict[str, np.ndarray]:
    """Element data as float arrays (scalars broadcast to :data:`COUNTS`): compliances finite and
    >= 0, rigidities (:data:`RIGIDITIES`) > 0 (``inf``: rigid); otherwise ``error`` naming the
    element (and ``owners[name][index]``). A value must be real numbers: bools (``True`` is not
    a compliance), text, ``None``, complex numbers and masked arrays are refused, naming the field."""
    from h4pin.inputs import describe, real_array  # h4pin.inputs imports nothing of h4pin.description
    from h4pin.limits import ELEMENT_RANGES, ImplausibleValueError

    out = {}
    prefix = f"{where}: " if where else ""
    for name in ELEMENTS:
        rigidity = name in RIGIDITIES
        raw = values.get(name, np.inf if rigidity else 0.0)
        n = COUNTS[name]
        what = f"a real number or {n} of them ({UNITS[name]})"
        if isinstance(raw, (list, tuple)) and any(isinstance(v, (bool, np.bool_)) for v in raw):
            raise error(f"{prefix}{name} must be {what} (not bools), got {describe(raw)}")
        arr = real_array(raw, f"{prefix}{name}", error, what)
        try:
            arr = np.broadcast_to(arr, (n,)).copy()
        except ValueError:
            raise error(f"{prefix}{name} must be {what}, got {describe(raw)}") from None
        bad = np.isnan(arr) | (arr <= 0.0) if rigidity else ~np.isfinite(arr) | (arr < 0.0)
        if np.any(bad):
            k = int(np.argmax(bad))
            owner = owners[name][k] if owners else element_name(name, k)
            rule = "> 0; inf switches it off" if rigidity else "finite and >= 0; 0 switches it off"
            raise error(f"{prefix}{owner}: {name} = {float(arr[k])!r} is not physical (must be {rule})")
        lo, hi = ELEMENT_RANGES[UNITS[name]]
        odd = (arr != 0.0) & np.isfinite(arr) & ((arr < lo) | (arr > hi))
        if np.any(odd):
            k = int(np.argmax(odd))
            owner = owners[name][k] if owners else element_name(name, k)
            off = "inf" if rigidity else "0"
            raise ImplausibleValueError(f"{prefix}{owner}: {name} = {float(arr[k]):g} {UNITS[name]} is outside the "
                                        f"plausible range [{lo:g}, {hi:g}] {UNITS[name]} ({off} switches it off; "
                                        "h4pin.limits.ELEMENT_RANGES)")
        arr.setflags(write=False)
        out[name] = arr
    return out


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
                                 f"{', '.join(ELEMENTS)}), got {len(args)} positional argument(s)")
        unknown = [n for n in values if n not in ELEMENTS]
        if unknown:
            raise ParameterError(f"Elements: no element kind {unknown[0]!r} (kinds: {', '.join(ELEMENTS)})")
        for k in KINDS:
            object.__setattr__(self, k.name, values.get(k.name, np.inf if k.rigidity else 0.0))
        self.__post_init__()

    def __reduce__(self) -> tuple[Any, ...]:
        """Unpickled (and deep-copied) through the constructor: checked like new ones."""
        return (_elements, ({n: np.array(getattr(self, n)) for n in ELEMENTS},))

    def __post_init__(self) -> None:
        checked = check_elements({n: getattr(self, n) for n in ELEMENTS})
        for name, value in checked.items():
            object.__setattr__(self, name, value)
        object.__setattr__(self, "_on", frozenset(n for n in ELEMENTS if is_on(n, checked[n])))

    def on(self, name: str) -> bool:
        """True when some element of kind ``name`` is switched on."""
        return name in self._on

    @property
    def off(self) -> bool:
        """True when every element is switched off (eq. 30 as it is)."""
        return not self._on

    def allclose(self, other: Elements, rtol: float = 1e-15) -> bool:
        """Every element equal to ``other``'s within ``rtol`` (relative; ``inf`` equals ``inf``)."""
        return all(np.allclose(getattr(self, n), getattr(other, n), rtol=rtol, atol=0.0) for n in ELEMENTS)


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


__all__ = ["AXES", "COUNTS", "ELEMENTS", "FORMS", "ILLUSTRATIVE", "KINDS", "RIGIDITIES", "SITES", "UNITS", "Elements",
           "Kind", "check_elements", "element_name", "is_on"]
