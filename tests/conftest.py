"""Test-suite wide pytest hooks.

``@pytest.mark.vcan`` tests need the Linux SocketCAN interface ``vcan0``; where it does not exist
they are skipped with the reason. ``tools/vcan-vm`` runs them in a guest that has it (``.ci/run``
does so after the host suite).

On every core (``pytest -n auto``, the README's test command, with ``--dist loadgroup
--no-loadscope-reorder`` from pyproject.toml): two workers per CPU (:data:`WORKERS_PER_CPU`), each
pinned to its CPU (:func:`cpus.pin_worker`); the tests of a file
with a module-scoped fixture form one group that runs on one worker (the fixture is built once);
the ``slow`` tests and groups are handed out first, so that the longest do not start last and
leave one worker idle at the end.

``--cpu-durations=N`` lists the N tests that took the most CPU time (user + system seconds of the
test's process and of the processes it started and waited for; setup, call and teardown), and the
suite's total: on a shared machine, where wall times say mostly how busy the others were.
"""

import os
import resource
import subprocess
from pathlib import Path

import pytest

try:                                  # pytest >= 9.2: structured node IDs
    from _pytest.nodeid import coerce_node_id
except ImportError:                   # before: xdist's own rewrite of the node ID works
    coerce_node_id = None

from cpus import ALL_CPUS, pin_worker
from processes import START_TIMEOUT, stop_process, wait_for_line

VCAN_CHANNEL = "vcan0"


def pytest_addoption(parser):
    parser.addoption("--cpu-durations", type=int, default=None, metavar="N",
                     help="list the N tests that took the most CPU time (user + system, their child processes "
                          "included) and the suite's total")


def _cpu_seconds() -> float:
    """User + system CPU seconds of this process and of its children waited for, so far."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Each phase's report carries its CPU seconds (``user_properties``: pytest-xdist sends them to
    the controller, which adds them up for ``--cpu-durations``)."""
    report = (yield).get_result()
    if item.config.getoption("cpu_durations") is not None:
        now = _cpu_seconds()
        report.user_properties.append(("cpu_seconds", now - getattr(item, "_cpu_mark", now)))
        item._cpu_mark = now


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    if item.config.getoption("cpu_durations") is not None:
        item._cpu_mark = _cpu_seconds()


def pytest_runtest_logreport(report):
    seconds = dict(report.user_properties).get("cpu_seconds")
    if seconds is not None:
        _CPU_BY_TEST[report.nodeid] = _CPU_BY_TEST.get(report.nodeid, 0.0) + seconds


_CPU_BY_TEST: dict[str, float] = {}


def pytest_terminal_summary(terminalreporter, config):
    n = config.getoption("cpu_durations")
    if n is None or not _CPU_BY_TEST:
        return
    terminalreporter.write_sep("=", f"most CPU time: {min(n, len(_CPU_BY_TEST))} of {len(_CPU_BY_TEST)} tests")
    for nodeid, seconds in sorted(_CPU_BY_TEST.items(), key=lambda kv: -kv[1])[:n]:
        terminalreporter.write_line(f"{seconds:8.2f}s  {nodeid}")
    terminalreporter.write_line(f"{sum(_CPU_BY_TEST.values()):8.2f}s  in all (user + system, child processes included)")


#: pytest-xdist workers per CPU under ``-n auto``: the real-time tests (a run on a periodic SYNC,
#: a HIL campaign in another process, a disturbed SYNC) leave their worker's CPU idle most of the
#: time they take (a disturbed-SYNC try: 3 s of CPU in 14 s); a second worker on each CPU fills it
WORKERS_PER_CPU = 2


def pytest_xdist_auto_num_workers(config):
    """``-n auto``: :data:`WORKERS_PER_CPU` workers on each CPU this process may use (each pinned
    to its CPU, :func:`cpus.pin_worker`); pytest-xdist's own count on a machine that cannot tell."""
    return WORKERS_PER_CPU * len(ALL_CPUS) if len(ALL_CPUS) > 1 else None


def pytest_configure(config):
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    if worker:
        pin_worker(worker)
        config.pluginmanager.register(_GroupInNodeId(), "ident-hw-group-in-node-id")


class _GroupInNodeId:
    """``--dist loadgroup`` on pytest 9.2: pytest-xdist 3.8 names an item's group by rewriting its
    ``_nodeid`` (``test@group``, read by the scheduler), which pytest 9.2 no longer reads (its node
    ID is the structured ``_id``): the groups were silently lost and every module fixture built on
    both workers (pytest-xdist issue 1386). Where the suffix did not take, it is written into the
    structured ID, as xdist's open fix does; nothing happens where xdist's own rewrite worked."""

    @pytest.hookimpl(trylast=True)      # after xdist's worker hook
    def pytest_collection_modifyitems(self, config, items):
        if coerce_node_id is None or not getattr(config.option, "loadgroup", False):
            return
        for item in items:
            names = {str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                     for m in item.iter_markers("xdist_group")}
            if names and "@" not in item.nodeid.rsplit("]", 1)[-1] and hasattr(item, "_id"):
                item._id = coerce_node_id(f"{item.nodeid}@{'_'.join(sorted(names))}")


def _shares_a_module_fixture(item) -> bool:
    """Whether ``item`` uses a module-scoped fixture of the project (not pytest's own)."""
    info = getattr(item, "_fixtureinfo", None)
    return info is not None and any(d.scope == "module" and d.baseid
                                    for defs in info.name2fixturedefs.values() for d in defs)


@pytest.hookimpl(tryfirst=True)      # before pytest-xdist's own, which reads the groups
def pytest_collection_modifyitems(config, items):
    """Group the tests that share a module fixture (``xdist_group``, one worker builds it) and
    hand out the slow work first (a unit's weight: its slow tests; a group without any ahead of
    single quick tests); skip the vcan tests where there is no vcan0."""
    unit = {}
    for item in items:
        if _shares_a_module_fixture(item):
            unit[id(item)] = item.nodeid.split("::", 1)[0]        # the file, relative to the root
            item.add_marker(pytest.mark.xdist_group(unit[id(item)]))
        else:
            unit[id(item)] = item.nodeid
    weight: dict[str, float] = {}
    for item in items:
        key = unit[id(item)]
        weight[key] = weight.get(key, 0.5 if key != item.nodeid else 0.0) + bool(item.get_closest_marker("slow"))
    first = {}
    for k, item in enumerate(items):
        first.setdefault(unit[id(item)], k)
    items.sort(key=lambda item: (-weight[unit[id(item)]], first[unit[id(item)]]))
    if Path("/sys/class/net", VCAN_CHANNEL).exists():
        return
    skip = pytest.mark.skip(
        reason=f"no SocketCAN interface {VCAN_CHANNEL} (/sys/class/net/{VCAN_CHANNEL} missing); "
        f"run them with: tools/vcan-vm -- python -m pytest -m vcan tests/vcan"
    )
    for item in items:
        if item.get_closest_marker("vcan"):
            item.add_marker(skip)


@pytest.fixture
def start_process():
    """``start(argv, ready)`` runs ``argv`` as another process and returns it once it printed a line
    starting with ``ready`` (it is then on the bus); all are stopped after the test."""
    procs = []

    def start(argv: list, ready: str) -> subprocess.Popen:
        proc = subprocess.Popen([str(arg) for arg in argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        procs.append(proc)
        wait_for_line(proc, ready, START_TIMEOUT)
        return proc

    yield start
    for proc in procs:
        stop_process(proc)
