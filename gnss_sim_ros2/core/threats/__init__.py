"""Threats to a GNSS receiver as timed scenario objects in the world (issue 29): jammers, spoofers and
receiver faults.

- ``scenario.py``: the scenario file (YAML, ``version: 1``, ``events:``), read and validated once;
- ``spectra.py``: normalised power spectral densities of the signals and the spectral separation coefficient;
- ``jamming.py``: received jammer power and the effective C/N0 of each signal, jamming indicator, AGC;
- ``faults.py``: receiver faults applied at their stage of the chain;
- ``runtime.py``: :class:`~.runtime.ThreatRuntime`, the one object the receiver chain calls (offline and in
  the nodes): interference on C/N0, faults on the clock, ranges and outputs, the truth labels, the spoofing hook;
- ``live.py``: events started and stopped while a run goes on (the receiver node's ``~/threats/start|stop``);
- ``timeline.py``: a run's C/N0, satellites, fix error and truth labels over time (``gnss-sim threats-plot``).

Layer: above ``receiver | visibility`` (it casts through the scene and reads the receiver's tables), below
``simulation`` (which builds it); the receiver takes it as an injected hook and never imports it.
"""
