"""Discovery of missing physics, a pipeline like PySINDy's (docs/thermal.md): readings, problem,
candidate library, splitters, selector, explainer, the wiring (``discover``), the words and the HTML
report, and the model a PLC can compute (``plcmodel``).

It may import ``nckemu.thermal.recordings``, ``nckemu.thermal.model`` and ``nckemu.thermal.stats``;
never the fleet, the synthetic machine or any commands module.
"""
