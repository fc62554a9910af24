"""Benchmark harnesses (``gnss-sim bench``, commands/bench.py, and bench/*.py): ``presets`` (speed against
accuracy of the fidelity presets), ``scaling`` (cost and memory against the size of the problem), ``speed``
(the offline speed targets against gnss_lib_py), ``timing`` (wall time of a repeated call). They run the
offline chain and print figures; no command line here."""
