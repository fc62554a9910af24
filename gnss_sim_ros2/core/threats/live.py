"""Events started and stopped while a run goes on (the receiver node's services ``~/threats/start`` and
``~/threats/stop``, for tests that react to the robot): one event of a scenario file as YAML text, checked by
the scenario file's validator (the same error texts) and by the runtime's own rules (a world position needs a
georeferenced scene; what the runtime does not simulate is refused), then put into the running
:class:`~.runtime.ThreatRuntime`: the same physics and the same truth labels as an event of the file.

Times count from the run start like the file's: ``start_s`` defaults to ``now_s`` (the next epoch), ``end_s`` to
the end of the run; stopping an event sets its ``end_s`` to ``now_s``.
"""
from __future__ import annotations

import dataclasses
import math

from .faults import OUTPUT_KINDS
from .runtime import ThreatRuntime
from .scenario import (
    FaultEvent,
    JammerEvent,
    Scenario,
    ScenarioError,
    SpooferEvent,
    _scenario_loader,
    parse_scenario,
)

START_WHERE = "threat event (~/threats/start)"


def event_from_text(text: str, taken_names, now_s: float, where: str = START_WHERE):
    """The validated event of the YAML text of one scenario event; :class:`ScenarioError` naming the line and key
    (``events[0].<key>``, as in a file).  ``taken_names``: names already used in the run (a name given twice is
    refused); without a name the event gets ``<type><n>``, the first n free."""
    import yaml

    try:
        node = yaml.compose(text, Loader=_scenario_loader())
        doc = yaml.load(text, Loader=_scenario_loader())
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{where}: not valid YAML: {exc}") from None
    if not isinstance(doc, dict):
        raise ScenarioError(f"{where}: expected one event, a mapping with 'type: jammer | spoofer | fault', got "
                            f"{doc!r}")
    doc = dict(doc)
    doc.setdefault("start_s", max(float(now_s), 0.0))
    doc.setdefault("end_s", math.inf)
    taken = set(taken_names)
    if "name" not in doc and isinstance(doc.get("type"), str):
        doc["name"] = next(f"{doc['type']}{n}" for n in range(len(taken) + 1) if f"{doc['type']}{n}" not in taken)
    # the event's own node under events[0], so that a message names the line of the text given
    at = (node.start_mark, node.end_mark)
    wrapper = yaml.MappingNode("tag:yaml.org,2002:map", [
        (yaml.ScalarNode("tag:yaml.org,2002:str", "events", *at), yaml.SequenceNode("tag:yaml.org,2002:seq", [node],
                                                                                      *at))], *at)
    event = parse_scenario({"version": 1, "events": [doc]}, wrapper, where).events[0]
    if event.name in taken:
        raise ScenarioError(f"{where}: event name {event.name!r} is already used in this run")
    return event


def start_event(runtime: ThreatRuntime, text: str, now_s: float) -> str:
    """Check the event of ``text`` (:func:`event_from_text`, then the runtime's rules on a scenario of it
    alone) and add it to ``runtime``; its name."""
    event = event_from_text(text, [e.name for e in runtime.scenario.events], now_s)
    ThreatRuntime(Scenario((event,), START_WHERE), runtime.scene, runtime.start)   # the runtime's rules
    _set_events(runtime, (*runtime.scenario.events, event))
    if isinstance(event, FaultEvent) and event.kind in OUTPUT_KINDS:
        runtime.output_faults.faults.append(event)
    return event.name


def stop_event(runtime: ThreatRuntime, name: str, now_s: float) -> None:
    """End event ``name`` at run time ``now_s`` (ValueError: no such event, or over already)."""
    events = list(runtime.scenario.events)
    k = next((i for i, e in enumerate(events) if e.name == name), None)
    if k is None:
        known = ", ".join(e.name for e in events) or "none"
        raise ValueError(f"no threat event {name!r} in this run (events: {known})")
    if events[k].end_s <= now_s:
        raise ValueError(f"threat event {name!r} is over already (end_s {events[k].end_s:g} s, now {now_s:g} s)")
    events[k] = dataclasses.replace(events[k], end_s=max(float(now_s), events[k].start_s))
    runtime.output_faults.faults = [events[k] if f.name == name else f for f in runtime.output_faults.faults]
    _set_events(runtime, tuple(events))


def _set_events(runtime: ThreatRuntime, events: tuple) -> None:
    lines = {e.name: runtime.scenario.lines.get(e.name) for e in events}
    runtime.scenario = dataclasses.replace(runtime.scenario, events=events, lines=lines)
    runtime.jammers = [e for e in events if isinstance(e, JammerEvent)]
    runtime.faults = [e for e in events if isinstance(e, FaultEvent)]
    if hasattr(runtime, "spoofers"):          # a runtime that keeps its spoofers' list (the spoofing model)
        runtime.spoofers = [e for e in events if isinstance(e, SpooferEvent)]
