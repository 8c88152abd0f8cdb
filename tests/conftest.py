"""Shared test settings: hypothesis profiles, the location of ../shared, results computed once per run, and
the real emulator (127.0.0.1, a free port) with an 828D collector's python-snap7 client that many areas use."""

from __future__ import annotations

import fcntl
import logging
import os
import pickle
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path
from typing import Any

import pytest
import snap7
from hypothesis import HealthCheck, settings

from nckemu.emulator.runner import EmulatorThread

settings.register_profile(
    "ci", max_examples=150, deadline=None,
    # On CI the examples are the same every run (a landing must not hinge on luck); locally they
    # vary from run to run and keep looking for new failures.
    derandomize=bool(os.environ.get("CI")),
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.register_profile(
    "long", max_examples=5000, deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

REPO = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True)
def _cli_log_handler_goes_with_its_test() -> Iterator[None]:
    """``cli.main`` run in a test's process leaves its log handler on the root logger, writing to the
    stream that test's capture opened; pytest closes that stream after the test, and a later record
    (a session closing on a module's server) then printed "--- Logging error ---". The handler goes
    with the test that set it."""
    yield
    root = logging.getLogger()
    for handler in [h for h in root.handlers if h.get_name() == "nckemu"]:
        root.removeHandler(handler)
        handler.close()


def _shared_dir() -> Path:
    """../shared beside the repository; in a git worktree elsewhere, beside the main checkout (the
    worktree's .git file names its gitdir, whose commondir leads back to the main .git)."""
    beside = REPO.parent / "shared"
    dot_git = REPO / ".git"
    if beside.is_dir() or not dot_git.is_file():
        return beside
    try:
        gitdir = Path(dot_git.read_text().removeprefix("gitdir:").strip())
        common = (gitdir / (gitdir / "commondir").read_text().strip()).resolve()
    except OSError:
        return beside
    return common.parent.parent / "shared"


SHARED = Path(os.environ["NCKEMU_SHARED"]) if os.environ.get("NCKEMU_SHARED") else _shared_dir()
FIXTURES = REPO / "fixtures"


@pytest.fixture
def shared_dir() -> Path:
    if not SHARED.is_dir():
        pytest.skip("../shared is not beside the repository")
    return SHARED


@pytest.fixture
def fixtures_dir() -> Path:
    return FIXTURES


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The twenty-seed matrices (``*_matrix.py``, one to two minutes each) first, the rest in their
    order: under xdist (``make slow``: two workers, work stealing) the longest tests start first, and
    the workers end together on short tests instead of one of them running a matrix alone at the end."""
    items.sort(key=lambda item: not item.path.name.endswith("_matrix.py"))


def _run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The test run's temporary directory: under pytest-xdist the one its workers share."""
    root = tmp_path_factory.getbasetemp()
    return root.parent if os.environ.get("PYTEST_XDIST_WORKER") else root


@pytest.fixture(scope="session")
def fixed_ports(tmp_path_factory: pytest.TempPathFactory) -> Callable[[], AbstractContextManager[None]]:
    """``with fixed_ports(): ...`` around a server whose ports are written in the example it runs (a fleet
    file, ``--base-port 21001``): one such server at a time among the run's xdist workers."""
    lock_path = _run_dir(tmp_path_factory) / "fixed-ports.lock"

    @contextmanager
    def held() -> Iterator[None]:
        with open(lock_path, "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            yield

    return held


@pytest.fixture(scope="session")
def once_per_run(tmp_path_factory: pytest.TempPathFactory) -> Callable[[str, Callable[[], Any]], Any]:
    """``once_per_run(name, produce)``: an expensive result that tests only read, computed once in a test
    run. Under pytest-xdist the first worker to ask computes it and pickles it into the run's temporary
    directory (shared by the workers, fresh each run); the others wait for it and load it."""
    root = _run_dir(tmp_path_factory)
    loaded: dict[str, Any] = {}

    def get(name: str, produce: Callable[[], Any]) -> Any:
        if name not in loaded:
            stored = root / f"once-{name}.pickle"
            with open(root / f"once-{name}.lock", "w") as lock:
                fcntl.flock(lock, fcntl.LOCK_EX)
                if stored.is_file():
                    loaded[name] = pickle.loads(stored.read_bytes())
                else:
                    loaded[name] = produce()
                    stored.write_bytes(pickle.dumps(loaded[name]))
        return loaded[name]

    return get


@pytest.fixture
def emulator() -> Iterator[EmulatorThread]:
    """The built-in default machine; a test module may override it (e.g. with other limits)."""
    with EmulatorThread() as emu:
        yield emu


@pytest.fixture
def collector(emulator: EmulatorThread) -> Iterator[snap7.Client]:
    """python-snap7 with an 828D collector's TSAPs (IOT and LSC): calling 0x0400, called 0x0D04
    (connection type 0x0D, rack 0, slot 4 in python-snap7's encoding)."""
    logging.getLogger("snap7").setLevel(logging.WARNING)
    client = snap7.Client()
    client.local_tsap = 0x0400
    client.connection_type = 0x0D
    client.connect("127.0.0.1", 0, 4, emulator.port)
    yield client
    client.disconnect()
