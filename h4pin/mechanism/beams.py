# SPDX-License-Identifier: Apache-2.0
"""Flexible links by the virtual joint method: :class:`Beam` and its virtual joints.

A flexible link is a straight Euler-Bernoulli beam (axial EA, torsion GJ, bending EIy and EIz;
no shear) from the origin of the joint that carries the link (its near end) to the link's other
attachment (its far end): the origin of its one child joint, or its one closure point; ``to``
picks one where there are several. Loads reach the link at its ends: the frames at the far end
(a closure frame, a link fixed there) move with it; every other frame and attachment of the link
stays with its near end. Section axes: x along the
span, y the link frame's axis most normal to x (projected), z = x × y.

The link's compliance at its far end, relative to its near end, is the cantilever's:
``C = ∫_0^L Bᵀ(s) D⁻¹ B(s) ds`` with, per bending plane, ``[[L³/3, L²/2], [L²/2, L]] / EI``.
It is carried by six virtual joints hung from the link's joint, all reading 0 at the reference
configuration, massless (the link's inertia stays as the file gives it):

* a slide along x, stiffness ``EA / L``; a hinge about x, ``GJ / L``;
* per bending plane, two hinges about the bending axis through the two Gauss-Legendre points of
  the span (``L/2 ∓ L/(2√3)`` from the near end), each of stiffness ``2 EI / L``: a two-point rule
  integrates the cantilever's ``∫ (s, 1)(s, 1)ᵀ ds / EI`` exactly, so the far end's 6 x 6
  compliance is the beam's to round-off. With ``segments = n``, two such hinges per plane in each
  of n equal segments, ``2 EI n / L`` each, the same far-end compliance. The hinges are chained
  from the near end to the far one (``bend_z1``, ``bend_y1`` at the first point, and so on), so
  that under load the chain bends as the beam does.

The same :func:`h4pin.mechanism.engine.insert_joints` hangs the H4's element joints.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import ParameterError
from h4pin.mechanism.engine import Insertion, VirtualJoint

#: The virtual joints of a beam on link ``<link>``: ``<link>_beam_<suffix>``.
SUFFIXES = ("axial", "torsion", "bend_z1", "bend_z2", "bend_y1", "bend_y2")
_GAUSS = (0.5 - 0.5 / math.sqrt(3.0), 0.5 + 0.5 / math.sqrt(3.0))
#: The most segments a beam takes (its virtual joints: 2 + 4 a segment).
MAX_SEGMENTS = 200


def _positive(name: str, value: Any, unit: str, rigid: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(f"Beam: {name} must be a number ({unit}), got {value!r}")
    v = float(value)
    if not (0.0 < v < math.inf or (rigid and v == math.inf)):
        raise ParameterError(f"Beam: {name} must be {'> 0 (inf: rigid)' if rigid else 'finite and > 0'} ({unit}), "
                             f"got {value!r}")
    return v


@dataclasses.dataclass(frozen=True)
class Beam:
    """A straight Euler-Bernoulli beam's section and material (SI): Young's modulus ``E`` (Pa),
    shear modulus ``G`` (Pa), area ``A`` (m²), second moments ``Iy``, ``Iz`` (m⁴, bending about
    the section's y and z axes), torsion constant ``J`` (m⁴) (``A``, ``Iy``, ``Iz``, ``J`` may be
    ``inf``: rigid that way, no virtual joint); ``to``: the far end's name (a child
    joint, a closure or a frame of the link) where the link has several; ``carry``: further
    attachments of the link (child joints, closures, frames) fixed to the far end rather than to
    the near one (a cross-bar at a forearm's tip, say); ``segments``: the span cut into that many
    equal segments, each with its two Gauss hinges per bending plane (``2 EI n / L`` each), in order
    from the near end: the far end's compliance is the same for any count, while the chain follows
    a bent beam's shape ever closer, so that a buckling load converges to Euler's as the count grows
    (``docs/loaded.md`` says how many give 1 %)."""

    E: float
    G: float
    A: float
    Iy: float
    Iz: float
    J: float
    to: str | None = None
    carry: tuple[str, ...] = ()
    segments: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.segments, bool) or not isinstance(self.segments, (int, np.integer)) or \
                not 1 <= self.segments <= MAX_SEGMENTS:
            raise ParameterError(f"Beam: segments must be an integer from 1 to {MAX_SEGMENTS}, got {self.segments!r}")
        object.__setattr__(self, "segments", int(self.segments))
        for name, unit in (("E", "Pa"), ("G", "Pa"), ("A", "m^2"), ("Iy", "m^4"), ("Iz", "m^4"), ("J", "m^4")):
            object.__setattr__(self, name, _positive(name, getattr(self, name), unit, rigid=name not in "EG"))
        if self.to is not None and not isinstance(self.to, str):
            raise ParameterError(f"Beam: to must be a name, got {self.to!r}")
        if isinstance(self.carry, str) or not all(isinstance(c, str) for c in self.carry):
            raise ParameterError(f"Beam: carry must be a tuple of names, got {self.carry!r}")
        object.__setattr__(self, "carry", tuple(self.carry))

    @classmethod
    def circle(cls, d: float, E: float, G: float, to: str | None = None) -> Beam:
        """A solid round section of diameter ``d`` (m)."""
        d = _positive("d", d, "m")
        return cls(E, G, math.pi * d**2 / 4, math.pi * d**4 / 64, math.pi * d**4 / 64, math.pi * d**4 / 32, to)

    @classmethod
    def tube(cls, d: float, t: float, E: float, G: float, to: str | None = None) -> Beam:
        """A round tube of outer diameter ``d`` and wall ``t`` (m, 0 < t < d/2)."""
        d, t = _positive("d", d, "m"), _positive("t", t, "m")
        if not t < d / 2:
            raise ParameterError(f"Beam.tube: the wall t = {t:g} m must be under half the diameter d = {d:g} m")
        di = d - 2 * t
        i = math.pi * (d**4 - di**4) / 64
        return cls(E, G, math.pi * (d**2 - di**2) / 4, i, i, 2 * i, to)

    @classmethod
    def rect(cls, b: float, h: float, E: float, G: float, to: str | None = None) -> Beam:
        """A solid rectangle, ``b`` (m) along the section's y axis and ``h`` (m) along z; torsion
        constant ``a c³ (1/3 - 0.21 c/a (1 - c⁴/(12 a⁴)))`` with a >= c the two sides (Roark's
        approximation, within about 0.5 % of the exact series)."""
        b, h = _positive("b", b, "m"), _positive("h", h, "m")
        a, c = max(b, h), min(b, h)
        j = a * c**3 * (1.0 / 3.0 - 0.21 * c / a * (1.0 - c**4 / (12.0 * a**4)))
        return cls(E, G, b * h, b * h**3 / 12, h * b**3 / 12, j, to)

    def joints(self, link: str, near: np.ndarray, far: np.ndarray, axes: np.ndarray) -> tuple[VirtualJoint, ...]:
        """The six virtual joints (module docstring) of this beam from ``near`` to ``far`` (world,
        m) with the link frame's ``axes`` (3 x 3, columns) at the reference configuration."""
        span = np.asarray(far, float) - np.asarray(near, float)
        length = float(np.linalg.norm(span))
        if not length > 0:
            raise ParameterError(f"beam on {link!r}: its two ends coincide (zero length)")
        x = span / length
        pick = int(np.argmin(np.abs(axes.T @ x)))
        y = axes[:, pick] - (axes[:, pick] @ x) * x
        y /= np.linalg.norm(y)
        z = np.cross(x, y)
        out = [VirtualJoint(f"{link}_beam_axial", "prismatic", x, near, self.E * self.A / length),
               VirtualJoint(f"{link}_beam_torsion", "revolute", x, near, self.G * self.J / length)]
        piece = length / self.segments
        for k, s in enumerate((i + g) * piece for i in range(self.segments) for g in _GAUSS):
            point = np.asarray(near, float) + s * x
            for axis, second, tag in ((z, self.Iz, "z"), (y, self.Iy, "y")):
                out.append(VirtualJoint(f"{link}_beam_bend_{tag}{k + 1}", "revolute", axis, point,
                                        2.0 * self.E * second / piece))
        return tuple(out)


def insertion(model: pin.Model, data: pin.Data, constraint_models: Any, link: str, beam: Beam) -> Insertion:
    """The :class:`~h4pin.mechanism.engine.Insertion` of ``beam`` on ``link`` (a body frame of
    ``model``; ``data`` at the reference configuration, frames placed).

    Raises:
        ParameterError: no such link, no far end, several without ``to`` (listed), a bad ``to``.
    """
    if not isinstance(beam, Beam):
        raise ParameterError(f"beams: {link!r} -> an h4pin.mechanism.Beam, got {beam!r}")
    if not isinstance(link, str) or not model.existFrame(link, pin.FrameType.BODY):
        bodies = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
        raise ParameterError(f"beams: no link {link!r} (links: {', '.join(bodies)})")
    joint = model.frames[model.getFrameId(link, pin.FrameType.BODY)].parentJoint
    if joint == 0:
        raise ParameterError(f"beams: link {link!r} is on the ground (no joint carries it)")
    om = data.oMi[joint]
    ends: dict[str, tuple[str, Any, np.ndarray]] = {}
    for j in range(1, model.njoints):
        if model.parents[j] == joint:
            ends[model.names[j]] = ("joint", j, (om * model.jointPlacements[j]).translation)
    for i, cm in enumerate(constraint_models):
        for side, (jid, place) in enumerate(((cm.joint1_id, cm.joint1_placement),
                                              (cm.joint2_id, cm.joint2_placement)), start=1):
            if jid == joint:
                ends[cm.name or f"closure_{i + 1}"] = ("closure", (i, side), (om * place).translation)
    if not ends and beam.to is None:
        raise ParameterError(f"beams: link {link!r} has no far end (no child joint, no closure on it; name a frame of "
                             "it with Beam(..., to=name))")
    if beam.to is None:
        if len(ends) > 1:
            raise ParameterError(f"beams: link {link!r} has several far ends: {', '.join(ends)}; pick one with "
                                 "Beam(..., to=name)")
        name = next(iter(ends))
    else:
        name = beam.to
        if name not in ends and model.existFrame(name):
            f = model.frames[model.getFrameId(name)]
            where = (om * f.placement).translation if f.parentJoint == joint else None
            hits = [n for n, e in ends.items() if where is not None and np.linalg.norm(e[2] - where) < 1e-12]
            name = hits[0] if hits else name
        own = model.existFrame(name) and model.frames[model.getFrameId(name)].parentJoint == joint
        if name not in ends and not own:
            raise ParameterError(f"beams: {beam.to!r} is not a far end of link {link!r} ({', '.join(ends)})")
    if name not in ends:  # a frame of the link that is no attachment: the far end is its origin
        f = model.frames[model.getFrameId(name)]
        ends[name] = ("frame", None, (om * f.placement).translation)
    kind, ref, far = ends[name]
    carried = []
    for c in beam.carry:
        if c in ends and c != name:
            carried.append(ends[c])
        elif c != name and model.existFrame(c) and model.frames[model.getFrameId(c)].parentJoint == joint:
            carried.append(("frame", None, (om * model.frames[model.getFrameId(c)].placement).translation))
        else:
            raise ParameterError(f"beams: carry {c!r} is not another attachment or frame of link {link!r} "
                                 f"({', '.join(ends)})")
    near = om.translation
    # every frame at the far end moves with it (a closure frame, a link fixed there), but the link's own
    length = float(np.linalg.norm(far - om.translation))
    frames = tuple(f.name for f in model.frames
                   if f.parentJoint == joint and f.type != pin.FrameType.JOINT and f.name != link
                   and np.linalg.norm((om * f.placement).translation - far) <= 1e-9 * max(length, 1e-3))
    every = [(kind, ref), *((k, r) for k, r, _ in carried)]
    frames = frames + tuple(c for c, (k, _, _) in zip(beam.carry, carried, strict=True) if k == "frame")
    return Insertion(model.names[joint], beam.joints(link, near, far, om.rotation),
                     children=tuple(model.names[r] for k, r in every if k == "joint"), frames=frames,
                     closures=tuple(r for k, r in every if k == "closure"))


__all__ = ["MAX_SEGMENTS", "SUFFIXES", "Beam", "insertion"]
