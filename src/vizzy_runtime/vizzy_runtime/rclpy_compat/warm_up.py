"""Work a node's construction does first, done ahead by its zygote (`vizzy run --zygote`, the
launcher's respawn_standby; zygote.py): Cyclone attaches XTypes type information to every topic,
and cyclonedds-python computes it in Python, about 25 ms per type (0.75 s of the sim's 3.3 s start
on a loaded machine). It is cached on each type's class, so computing it before the fork takes it
off every start and respawn. No participant is created: the zygote stays invisible on the network
and starts no thread (fork() copies only the forking one)."""

from __future__ import annotations

from .. import dds, msgs
from . import param_services

# Types every node's runtime uses (rosout, parameter events, /clock, the graph topic, diagnostics).
RUNTIME_TYPES = ('rcl_interfaces/msg/Log', 'rcl_interfaces/msg/ParameterEvent',
                 'rosgraph_msgs/msg/Clock',
                 'rmw_dds_common/msg/ParticipantEntitiesInfo',
                 'diagnostic_msgs/msg/DiagnosticArray',
                 'tf2_msgs/msg/TFMessage')


def warm_up() -> int:
    """Compute the type information of the message types loaded so far (the node module's
    message() calls), the runtime's own and the parameter services'. Returns how many types."""
    names = set(msgs.loaded_types()) | set(RUNTIME_TYPES)
    classes = [dds.idl_type(name) for name in sorted(names)]
    classes += [param_services.wire_type(f'rcl_interfaces/srv/{srv}_{half}')
                for srv in param_services.SERVICES.values() for half in ('Request', 'Response')]
    for cls in classes:
        cls.__idl__.fill_type_data()
    return len(classes)
