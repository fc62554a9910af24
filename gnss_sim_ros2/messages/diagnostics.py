"""``diagnostic_msgs`` of the nodes: one DiagnosticStatus from a name, a message and {key: value}, and the
``/diagnostics`` DiagnosticArray that carries it."""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from std_msgs.msg import Header


def diagnostic_status(name: str, message: str, values: dict, warn: bool = False,
                      hardware_id: str = "gnss_sim") -> DiagnosticStatus:
    """A status at level WARN (``warn``) or OK; ``values`` become its KeyValues in their order (str values)."""
    return DiagnosticStatus(level=DiagnosticStatus.WARN if warn else DiagnosticStatus.OK, name=name,
                            message=message, hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])


def diagnostic_array(stamp, *statuses: DiagnosticStatus) -> DiagnosticArray:
    """The /diagnostics message of ``statuses`` at ``stamp`` (builtin_interfaces/Time)."""
    return DiagnosticArray(header=Header(stamp=stamp), status=list(statuses))
