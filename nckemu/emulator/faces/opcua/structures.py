"""asyncua structures the face fills whose field names differ between asyncua's majors.

asyncua 1.1 named a field ``StatusCode_`` or ``NodeClass_`` where the type of the same name would
clash (with a read-only or read-write property ``StatusCode``/``NodeClass`` beside it); 2.x names the
fields ``StatusCode`` and ``NodeClass``. The face fills those fields by position or by attribute,
which both take, so that it runs on either while installs move to 2.x.
"""

from __future__ import annotations

from typing import Any

from asyncua import ua


def status_value(status: ua.StatusCode) -> ua.DataValue:
    """A value that is a status alone (a refused or failed read)."""
    return ua.DataValue(None, status)


def refused_item(status: ua.StatusCode) -> ua.MonitoredItemCreateResult:
    """The result of a monitored item that was not created."""
    return ua.MonitoredItemCreateResult(status)


def reference(node_class: ua.NodeClass, **fields: Any) -> ua.ReferenceDescription:
    """A reference description to a node of ``node_class`` (the other fields by name)."""
    described = ua.ReferenceDescription(**fields)
    described.NodeClass = node_class
    return described
