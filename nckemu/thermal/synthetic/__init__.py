"""The synthetic machine: scenarios and run families with a known answer, for tests and benches.

It may import ``nckemu.thermal.recordings`` and ``nckemu.thermal.model``; never discovery (a
scenario's truth must not be shaped by what finds it) nor the fleet.
"""
