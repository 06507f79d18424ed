"""Logs in: real vehicles' logs through mapping files, and simulated logs.

Modules, one concern each: :mod:`.mapping` (the mapping file), :mod:`.readers` (bags and text
logs as tables), :mod:`.importer` (a log -> the contract's signals, with its import report),
:mod:`.contract_bag` (an imported log as the contract's arrays and bag, with provenance),
:mod:`.segments` (continuous stretches, resampling on request), :mod:`.derive` (signals
derived from others, said), :mod:`.units` (units and scales), :mod:`.limits` (logged actuator
values outside a vehicle file's limits), :mod:`.simlog` (simulated runs written as bags),
:mod:`.synth` (vendor-format logs of simulated runs), :mod:`.cli` (``auv import``).
"""
