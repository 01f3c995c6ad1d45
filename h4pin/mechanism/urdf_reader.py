# SPDX-License-Identifier: Apache-2.0
"""A URDF read as text and checked before Pinocchio builds its model, for
:meth:`h4pin.mechanism.Mechanism.from_urdf` (and the H4's own reader,
:mod:`h4pin.description.urdf`, which shares these checks).

* :func:`decode`: the file's bytes as text, in the encoding its byte-order mark or its XML
  declaration states (UTF-8 without either, as XML says); a binary file, an unknown encoding or
  bytes that are not in it are a :class:`~h4pin.errors.MalformedURDFError`.
* :func:`parse` and :func:`check_tree`: well-formed XML with a ``<robot>`` root, then what
  Pinocchio's parser would fail on with a bare message, print on the console or pass silently:
  duplicate link or joint names, a joint naming a link the file lacks, origins, axes, limits,
  masses and inertias that are not finite numbers, an origin farther than
  ``h4pin.limits.RANGES["robot length"]`` (1 km: a ``1e308`` there overflows every product with
  it), a zero axis, reversed limits, a negative mass or an inertia that is not positive
  semi-definite, an axis of zero length or one whose length overflows. Each error names the
  element and the attribute.
* :func:`read`: the file (a regular file of bounded size: :func:`h4pin.files.read_input`)
  through the above into Pinocchio's model, built from the text (``buildModelFromXML``), so that
  a file at a path that is not UTF-8 is read as any other; what Pinocchio's C++ parser prints on
  the console goes into the error's message, never on the terminal.
"""

from __future__ import annotations

import codecs
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from h4pin.errors import MalformedURDFError
from h4pin.files import captured_stderr, read_input
from h4pin.limits import RANGES

#: Byte-order marks, longest first, and the codec each starts.
_BOMS = ((codecs.BOM_UTF32_LE, "utf-32"), (codecs.BOM_UTF32_BE, "utf-32"), (codecs.BOM_UTF16_LE, "utf-16"),
         (codecs.BOM_UTF16_BE, "utf-16"), (codecs.BOM_UTF8, "utf-8-sig"))
#: The XML declaration's encoding, read from the first bytes of a file.
_ENCODING = re.compile(rb"^\s*<\?xml[^>]*?\bencoding\s*=\s*[\"']([A-Za-z0-9._:-]+)[\"']")


def decode(data: bytes, where: str) -> str:
    """URDF (XML) bytes as text: in the encoding of its byte-order mark (UTF-8, UTF-16, UTF-32),
    else in the one its XML declaration states (UTF-8 without one); binary content, an unknown
    encoding or bytes that are not in it are a :class:`MalformedURDFError` naming ``where``."""
    bom = next((codec for mark, codec in _BOMS if data.startswith(mark)), None)
    if bom is not None:  # UTF-16 and UTF-32 text holds NUL bytes: its byte-order mark says which
        try:
            return data.decode(bom).removeprefix("\ufeff")
        except UnicodeDecodeError as exc:
            raise MalformedURDFError(f"{where}: not {bom} text, though it starts with its byte-order mark "
                                     f"({exc.reason} at byte {exc.start})") from None
    if b"\0" in data:
        raise MalformedURDFError(f"{where}: a binary file, not a URDF (XML text)")
    m = _ENCODING.match(data[:1024])
    encoding = m.group(1).decode("ascii") if m else "utf-8"
    try:
        codecs.lookup(encoding)
    except LookupError:
        raise MalformedURDFError(f"{where}: its XML declaration states the encoding {encoding!r}, which Python "
                                 "does not know") from None
    try:
        text = data.decode(encoding)
    except UnicodeDecodeError as exc:
        said = "" if m else " (its XML declaration states no other encoding)"
        raise MalformedURDFError(f"{where}: not {'UTF-8' if not m else encoding} text{said} ({exc.reason} at byte "
                                 f"{exc.start})") from None
    return text.removeprefix("\ufeff")


def parse(text: str, where: str) -> ET.Element:
    """The ``<robot>`` root of URDF text, or a :class:`MalformedURDFError` naming ``where``."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise MalformedURDFError(f"{where}: not well-formed XML ({exc})") from None
    if root.tag != "robot":
        raise MalformedURDFError(f"{where}: the root element is <{root.tag}>, not <robot>")
    return root


def attribute(elem: ET.Element | None, key: str, where: str, what: str) -> str:
    """``elem``'s attribute ``key``, or a :class:`MalformedURDFError` naming ``what``."""
    if elem is None or elem.get(key) is None:
        raise MalformedURDFError(f"{where}: {what} is missing attribute '{key}'")
    return elem.get(key)  # type: ignore[return-value]


def floats(text: str, n: int, where: str, what: str) -> np.ndarray:
    """``n`` finite numbers from an attribute's text, or a :class:`MalformedURDFError` naming ``what``."""
    try:
        v = np.array([float(t) for t in text.split()])
    except ValueError:
        raise MalformedURDFError(f"{where}: {what} = {text!r} is not a list of numbers") from None
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise MalformedURDFError(f"{where}: {what} = {text!r} must be {n} finite numbers")
    return v


def _check_names(root: ET.Element, where: str) -> None:
    """Duplicate link or joint names, a joint's parent or child that is no link of the file."""
    for kind in ("link", "joint"):
        seen: set[str] = set()
        for elem in root.findall(kind):
            name = attribute(elem, "name", where, f"a <{kind}>")
            if name in seen:
                raise MalformedURDFError(f"{where}: two <{kind}> elements are named '{name}'")
            seen.add(name)
    links = {elem.get("name") for elem in root.findall("link")}
    for j in root.findall("joint"):
        for side in ("parent", "child"):
            ref = j.find(side)
            link = None if ref is None else ref.get("link")
            if link not in links:
                raise MalformedURDFError(f"{where}: joint '{j.get('name')}' names {side} link '{link}', which is not a "
                                         "<link> of the file")


def _check_origins(root: ET.Element, where: str) -> None:
    """Every origin's ``xyz`` and ``rpy``: three finite numbers, ``xyz`` within the plausible
    length of a robot (:data:`h4pin.limits.RANGES`)."""
    lo, hi, unit, what = RANGES["robot length"]
    for parent in root.iter():
        for elem in parent:
            if elem.tag == "origin" or elem.tag.endswith("_origin"):
                for key in ("xyz", "rpy"):
                    if elem.get(key) is None:
                        continue
                    label = f"<{elem.tag} {key}> in <{parent.tag}> '{parent.get('name') or '?'}'"
                    v = floats(elem.get(key), 3, where, label)
                    if key == "xyz" and not np.all((v >= lo) & (v <= hi)):
                        raise MalformedURDFError(f"{where}: {label} = {elem.get(key)!r} is outside the plausible range "
                                                 f"[{lo:g}, {hi:g}] {unit} of {what} (h4pin.limits.RANGES)")


def check_tree(root: ET.Element, where: str) -> None:
    """The checks Pinocchio's URDF parser would fail on with a bare message (or pass silently):
    the module docstring's list. Each error names the element."""
    _check_names(root, where)
    _check_origins(root, where)
    for j in root.findall("joint"):
        name, kind = j.get("name"), j.get("type")
        axis = j.find("axis")
        if kind in ("revolute", "continuous", "prismatic") and axis is not None:
            a = floats(axis.get("xyz", "1 0 0"), 3, where, f"<axis xyz> of joint '{name}'")
            if not 1e-18 < sum(float(x) * float(x) for x in a) < float("inf"):  # Python floats: inf, no warning
                raise MalformedURDFError(f"{where}: joint '{name}' has a zero <axis xyz=\"{axis.get('xyz')}\"> (or one "
                                         "whose length overflows)")
        limit = j.find("limit")
        if limit is not None and kind in ("revolute", "prismatic"):
            lo = floats(limit.get("lower", "0"), 1, where, f"<limit lower> of joint '{name}'")[0]
            hi = floats(limit.get("upper", "0"), 1, where, f"<limit upper> of joint '{name}'")[0]
            if lo > hi:
                raise MalformedURDFError(f"{where}: joint '{name}' has <limit lower=\"{lo:g}\"> above upper=\"{hi:g}\"")
    for link in root.findall("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        name = link.get("name")
        mass = inertial.find("mass")
        if mass is not None:
            m = floats(mass.get("value", "0"), 1, where, f"<mass value> of link '{name}'")[0]
            if m < 0:
                raise MalformedURDFError(f"{where}: link '{name}' has a negative <mass value=\"{m:g}\">")
        inertia = inertial.find("inertia")
        if inertia is not None:
            keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
            v = {k: floats(inertia.get(k, "0"), 1, where, f"<inertia {k}> of link '{name}'")[0] for k in keys}
            tensor = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]],
                               [v["ixz"], v["iyz"], v["izz"]]])
            if np.linalg.eigvalsh(tensor).min() < -1e-12 * max(np.abs(tensor).max(), 1e-300):
                raise MalformedURDFError(f"{where}: link '{name}' has an <inertia> that is not positive "
                                         "semi-definite")


def read(path: Any, *, free_flyer: bool = False, what: str = "URDF") -> pin.Model:
    """Pinocchio's model of the URDF file ``path`` (module docstring); ``free_flyer``: its root
    on a free-flyer joint.

    Raises:
        InputFileError: not a regular file of bounded size (:func:`h4pin.files.read_input`).
        MalformedURDFError: as :func:`decode`, :func:`parse` and :func:`check_tree`, or Pinocchio
            cannot build it (its message, and what its parser printed).
    """
    data = read_input(path, what)
    path = Path(path)
    text = decode(data, str(path))
    check_tree(parse(text, str(path)), str(path))
    try:
        with captured_stderr() as printed:
            model = (pin.buildModelFromXML(text, pin.JointModelFreeFlyer()) if free_flyer
                     else pin.buildModelFromXML(text))
    except (RuntimeError, ValueError, IndexError) as exc:
        said = " ".join(" ".join(printed).split())
        raise MalformedURDFError(f"{path}: Pinocchio cannot read it ({' '.join(str(exc).split())}"
                                 f"{'; it says: ' + said if said else ''})") from None
    if any(printed):  # a success that printed something: shown as it would have been
        print("\n".join(p for p in printed if p), file=sys.stderr)
    return model


__all__ = ["attribute", "check_tree", "decode", "floats", "parse", "read"]
