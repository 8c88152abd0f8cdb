"""Fleet discovery on real Dask: in this process's local cluster, through a scheduler and workers the
test starts on 127.0.0.1, with a worker killed mid-run, and against an unreachable scheduler."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from nckemu.thermal.fleet.discover import discover_fleet, discover_machine, scan_root
from nckemu.thermal.model.terms import render_model
from nckemu.thermal.recordings.recording import write_recording
from nckemu.thermal.synthetic.scenarios import make_scenario

pytest.importorskip("distributed")

REPO = Path(__file__).resolve().parents[3]
DASK = Path(sys.executable).with_name("dask")
SCENARIOS = ("thermal_lag", "gain_error", "null_ar1", "thermal_lag")


def _write_fleet(root: Path, hours: float) -> Path:
    for index, scenario in enumerate(SCENARIOS):
        made = make_scenario(scenario, seed=20 + index, duration_h=hours)
        folder = root / f"m{index + 1:02d}"
        folder.mkdir(parents=True)
        half = made.recording.t_s < made.recording.t_s[len(made.recording.t_s) // 2]
        write_recording(folder / "run1.csv", made.recording.slice(half))
        write_recording(folder / "run2.csv", made.recording.slice(~half))
        (folder / "model.toml").write_text(render_model(made.baseline), encoding="utf-8")
    return root


@pytest.fixture(scope="module")
def fleet_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _write_fleet(tmp_path_factory.mktemp("fleet"), 24.0)


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class _DaskCluster:
    """``dask scheduler`` and ``dask worker`` processes (no nanny: killing one kills its tasks)."""

    def __init__(self, workers: int) -> None:
        self.address = f"tcp://127.0.0.1:{_free_port()}"
        port = self.address.rsplit(":", 1)[1]
        quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "cwd": REPO}
        self.scheduler = subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", port,
                                           "--no-dashboard"], **quiet)  # type: ignore[call-overload]
        self.workers = [subprocess.Popen([str(DASK), "worker", self.address, "--nthreads", "1", "--no-nanny",
                                          "--no-dashboard", "--host", "127.0.0.1", "--name", f"w{i}"],
                                         **quiet)  # type: ignore[call-overload]
                        for i in range(workers)]
        from distributed import Client

        with Client(self.address, timeout="30s") as client:
            client.wait_for_workers(workers, timeout=60)

    def close(self) -> None:
        for process in [*self.workers, self.scheduler]:
            if process.poll() is None:
                process.terminate()
        for process in [*self.workers, self.scheduler]:
            try:
                # a scheduler with a client gone can take ~20 s to honour SIGTERM; nothing is asserted
                # after this, so it need not be waited for
                process.wait(timeout=3)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


@pytest.fixture
def dask_cluster() -> Iterator[_DaskCluster]:
    if not DASK.exists():
        pytest.skip(f"no dask command beside {sys.executable}")
    cluster = _DaskCluster(2)
    try:
        yield cluster
    finally:
        cluster.close()


def _findings(document: dict[str, object]) -> dict[str, object]:
    return {m["machine"]: m["findings"] for m in document["machines"]}  # type: ignore[index,union-attr]


def test_same_findings_in_process_on_a_local_cluster_and_through_a_scheduler(
        fleet_root: Path, dask_cluster: _DaskCluster, tmp_path: Path) -> None:
    machines = scan_root(fleet_root)
    reference = {m.name: discover_machine(m)["findings"] for m in machines}
    assert [e["effect"] for e in reference["m02"]["missing_physics"]] == ["gain_error"]
    local = discover_fleet(machines, workers=2)
    assert local["engine"] == "local cluster, 2 worker(s)" and _findings(local) == reference
    out = tmp_path / "fleet.json"
    run = subprocess.run([sys.executable, "-m", "nckemu", "discover", "--fleet", str(fleet_root), "--scheduler",
                          dask_cluster.address, "--json-out", str(out), "--report", str(tmp_path / "fleet.html")],
                         cwd=REPO, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    remote = json.loads(out.read_text(encoding="utf-8"))
    assert remote["engine"] == dask_cluster.address and _findings(remote) == reference
    workers = {m["worker"] for m in remote["machines"]}
    assert all(w.startswith("tcp://127.0.0.1:") for w in workers)
    assert remote["table"][0]["effect"] == "thermal_lag" and remote["table"][0]["machines"] == 2
    assert "m01: thermal_lag" in run.stdout and "thermal_lag: 2 of 4 machines" in run.stdout
    assert "gain_error" in (tmp_path / "fleet.html").read_text(encoding="utf-8")


@pytest.mark.slow  # a worker killed and a task retried: 50 s on two cores (the default run keeps the cluster test)
def test_a_worker_killed_mid_run_is_retried_and_the_result_says_so(
        tmp_path: Path, dask_cluster: _DaskCluster) -> None:
    from distributed import Client

    root = _write_fleet(tmp_path / "long", 24.0 * 7)  # ~1 s of discovery per machine
    machines = scan_root(root)
    with Client(dask_cluster.address, timeout="30s") as watcher:
        pids = watcher.run(os.getpid)
        outcome: dict[str, object] = {}
        thread = threading.Thread(target=lambda: outcome.update(
            document=discover_fleet(machines, scheduler=dask_cluster.address)))
        thread.start()
        killed = None
        deadline = time.monotonic() + 60
        while killed is None and time.monotonic() < deadline:
            busy = [worker for worker, keys in watcher.processing().items() if keys]
            if busy:
                killed = busy[0]
                os.kill(pids[killed], signal.SIGKILL)
            time.sleep(0.02)
        thread.join(timeout=240)
    assert killed is not None
    document = outcome["document"]
    assert isinstance(document, dict)
    assert document["retried"], "no task was reported as retried"
    assert not document["failed"]
    assert all(m["worker"] != killed for m in document["machines"])
    reference = {m.name: discover_machine(m)["findings"] for m in machines[:1]}
    assert _findings(document)["m01"] == reference["m01"]


def test_an_unreachable_scheduler_is_one_line_and_exit_1_within_the_timeout(fleet_root: Path) -> None:
    address = f"tcp://127.0.0.1:{_free_port()}"
    started = time.monotonic()
    run = subprocess.run([sys.executable, "-m", "nckemu", "discover", "--fleet", str(fleet_root),
                          "--scheduler", address, "--json-out", "-"], cwd=REPO, capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 1
    assert run.stderr.count("\n") == 1 and "Traceback" not in run.stderr, run.stderr
    assert f"--scheduler {address}: cannot reach it within 10 s" in run.stderr
    assert time.monotonic() - started < 60


@pytest.mark.slow  # two reductions and three fleet discoveries: 25-150 s on two cores
def test_reducing_days_first_keeps_the_findings_and_redoes_only_what_changed(tmp_path: Path) -> None:
    """1 machine-day = 1 file at 5 s; stage 1 reduces each to 60 s means on the cluster, stage 2 names
    the same physics per machine as on the raw files, with the same held-out figures (before within 5 %,
    after no worse by more than 10 %); a second run
    finds every file up to date, and a day written again is the only one reduced again."""
    root = tmp_path / "fleet"
    for index, scenario in enumerate(("thermal_lag", "gain_error", "null_ar1")):
        made = make_scenario(scenario, seed=40 + index, duration_h=48.0, dt_s=5.0)
        folder = root / f"m{index + 1:02d}"
        folder.mkdir(parents=True)
        for day in range(2):
            inside = (made.recording.t_s >= day * 86400.0) & (made.recording.t_s < (day + 1) * 86400.0)
            suffix = "parquet" if index == 1 else "csv"
            write_recording(folder / f"day{day + 1:03d}.{suffix}", made.recording.slice(inside))
        (folder / "model.toml").write_text(render_model(made.baseline), encoding="utf-8")
    machines = scan_root(root)
    raw = discover_fleet(machines, workers=1, root=str(root))
    reduced = discover_fleet(machines, workers=1, root=str(root), reduce_step_s=60.0)
    assert reduced["reduce"]["files"] == 6 and reduced["reduce"]["reduced"] == 6 and not reduced["reduce"]["failed"]
    assert reduced["reduce"]["rows_out"] * 12 == reduced["reduce"]["rows_in"]
    for name, findings in _findings(raw).items():
        ours = _findings(reduced)[name]
        assert [e["effect"] for e in ours["missing_physics"]] == [e["effect"] for e in findings["missing_physics"]]
        # the same baseline error; after the fit no worse by more than 10 % (60 s means carry less gauge
        # noise, so it may come out lower)
        assert ours["heldout_rms_before_um"] == pytest.approx(findings["heldout_rms_before_um"], rel=0.05)
        if findings["missing_physics"]:
            assert ours["heldout_rms_after_um"] <= 1.10 * findings["heldout_rms_after_um"]
    assert {p.name for p in (root / "_60s" / "m02").iterdir()} == {"day001.parquet", "day002.parquet"}
    again = discover_fleet(scan_root(root), workers=1, root=str(root), reduce_step_s=60.0)
    assert again["reduce"]["up_to_date"] == 6 and again["reduce"]["reduced"] == 0
    later = time.time() + 5
    os.utime(root / "m01" / "day002.csv", (later, later))
    third = discover_fleet(scan_root(root), workers=1, root=str(root), reduce_step_s=60.0)
    assert third["reduce"]["reduced"] == 1 and third["reduce"]["up_to_date"] == 5
