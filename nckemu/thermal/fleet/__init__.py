"""Fleet discovery: every machine folder's discovery as a Dask task, the day files reduced to window
means first, the fleet table, and ``nckemu discover --fleet``.

It sits on top of discovery: it may import every other part of thermal/ but the commands of
``nckemu.thermal.commands``.
"""
