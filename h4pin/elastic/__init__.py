# SPDX-License-Identifier: Apache-2.0
"""The H4 as an elastic closed-loop Pinocchio model, a client of :mod:`h4pin.mechanism`.

* :func:`elastic_model` (:mod:`h4pin.elastic.h4`): the H4 with every compliance of eq. 30 and of
  its optional elements as virtual joints; an independent route to :func:`h4pin.compliance`
  (``model="consistent"``), and a :class:`~h4pin.mechanism.Mechanism`
  (:attr:`ElasticH4.mechanism <h4pin.elastic.h4.ElasticH4.mechanism>`). See ``docs/elastic.md``;
* :func:`modes` (:mod:`h4pin.elastic.modal`): the natural frequencies and mode shapes of the
  elastic H4 with the URDF's link inertias and a payload. See ``docs/modes.md``.

The generic names that lived here (``Mechanism``, ``Beam``, ``Payload``, ...) are in
:mod:`h4pin.mechanism`; the old paths warn until h4pin 0.3.0 (:mod:`h4pin.deprecations`).
"""

from h4pin.deprecations import module_getattr
from h4pin.elastic.h4 import ElasticH4, elastic_model
from h4pin.elastic.modal import modes

__getattr__ = module_getattr(__name__)

__all__ = ["ElasticH4", "elastic_model", "modes"]
