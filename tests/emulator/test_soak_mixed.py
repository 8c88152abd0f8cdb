"""bench/soak_mixed.py at its tiny size: a living machine (recording, PLC program) with S7 clients,
python-snap7 SZL reads and OPC UA sessions at once, with --state; one life (no monitored change lost),
then a kill -9 and restart (no acknowledged write lost, S7 or OPC UA, nothing torn)."""

from __future__ import annotations

import pytest

from bench.soak_mixed import SIZES, run, verdict

pytestmark = pytest.mark.timeout(600)


# The kill -9 life is slow (make slow: 20-40 s on two cores); test_retained_state.py kills a server in a
# write burst in the default run.
@pytest.mark.parametrize("kills", [0, pytest.param(1, marks=pytest.mark.slow)], ids=["one life", "kill -9"])
def test_the_mixed_soak_tiny(kills: int) -> None:
    clients, jobs, sessions, operations, _kills, seconds = SIZES["tiny"]
    result = run(clients, jobs, sessions, operations, kills, seconds)
    assert not verdict(result, kills), (verdict(result, kills), result)
    assert result["s7"]["jobs"] >= clients * jobs and result["opcua"]["operations"] >= sessions * operations // 2
    if kills:
        assert result["kills"] == kills
    else:
        assert result["opcua"]["changes_written"] and result["opcua"]["changes_seen"] >= result["opcua"]["changes_written"]
