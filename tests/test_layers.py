"""The project's import layers (developers' brief), checked on the source with ``ast``.

* ``ident_hw.model`` is pure math: it imports nothing else of the project.
* ``trajectories`` and the simulated rig (``drivers.sim``) may import the model, nothing above it.
* the drive driver (``drivers`` outside ``drivers.sim``) never imports ``ident_hw`` nor the rig.
* only the experiment runner (``ident_hw.experiment``) and the CLI wire drivers and trajectories together.
* nothing imports the CLI; no import cycles between modules.
"""

import ast
import functools
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ident_hw", "drivers", "trajectories")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def project_imports(path: Path) -> set[str]:
    """Project modules imported by ``path`` (absolute names, relative imports resolved)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    own = module_name(path)
    package = own if path.name == "__init__.py" else own.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                prefix = ".".join(base + ([node.module] if node.module else []))
            else:
                prefix = node.module or ""
            names = [prefix] + [f"{prefix}.{alias.name}" for alias in node.names]
        else:
            continue
        found.update(n for n in names if n.split(".")[0] in PACKAGES)
    return found


MODULES = {module_name(p): p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")}


@functools.cache
def imports() -> dict[str, set[str]]:
    """Each module's project imports (parsed once, when a test first asks: not at collection)."""
    return {name: {i for i in project_imports(path) if i in MODULES or i.rpartition(".")[0] in MODULES}
            for name, path in MODULES.items()}


def within(name: str, package: str) -> bool:
    return name == package or name.startswith(package + ".")


def offenders(source: str, forbidden, allowed=()):
    return sorted((m, i) for m, imports in imports().items() if within(m, source)
                  for i in imports
                  if any(within(i, f) for f in forbidden) and not any(within(i, a) for a in allowed))


def test_model_imports_nothing_else_of_the_project():
    assert offenders("ident_hw.model", PACKAGES, allowed=("ident_hw.model",)) == []


def test_trajectories_import_only_the_model():
    assert offenders("trajectories", PACKAGES, allowed=("trajectories", "ident_hw.model")) == []


def test_master_side_driver_never_imports_ident_hw_or_the_rig():
    bad = [(m, i) for m, i in offenders("drivers", ("ident_hw", "drivers.sim", "trajectories"))
           if not within(m, "drivers.sim")]
    assert bad == []


def test_simulated_rig_imports_only_the_model_and_drivers():
    assert offenders("drivers.sim", ("ident_hw", "trajectories"), allowed=("ident_hw.model",)) == []


def test_only_the_runner_and_cli_wire_drivers_and_trajectories():
    bad = [(m, i) for m, i in offenders("ident_hw", ("drivers", "trajectories"))
           if not (within(m, "ident_hw.experiment") or within(m, "ident_hw.cli"))]
    # ident_hw.config maps YAML to the drivers' and trajectories' own settings classes: allowed
    assert [(m, i) for m, i in bad if not within(m, "ident_hw.config")] == []


def test_nothing_imports_the_cli():
    assert [m for m, imports in imports().items() if any(within(i, "ident_hw.cli") for i in imports)
            and not within(m, "ident_hw.cli")] == []


def to_module(name: str) -> str:
    return name if name in MODULES else name.rpartition(".")[0]


def test_no_import_cycles():
    graph = {m: {to_module(i) for i in imports} - {m} for m, imports in imports().items()}
    # a package's __init__ re-exporting its submodules is not a cycle of logic: drop parent -> child edges
    graph = {m: {i for i in deps if not within(i, m)} for m, deps in graph.items()}
    state, stack = {}, []

    def visit(m):
        state[m] = "open"
        stack.append(m)
        for d in graph.get(m, ()):
            if state.get(d) == "open":
                pytest.fail("import cycle: " + " -> ".join(stack[stack.index(d):] + [d]))
            if d not in state:
                visit(d)
        stack.pop()
        state[m] = "done"

    for m in sorted(graph):
        if m not in state:
            visit(m)


def _robot_kind_compares(path: Path) -> list[int]:
    """Lines of ``path`` that compare a robot's kind (``robot.kind`` or ``config.robot.kind``,
    ``kind`` of anything named robot) with something, or test it for membership."""
    lines = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if not isinstance(node, ast.Compare):
            continue
        for operand in [node.left, *node.comparators]:
            if isinstance(operand, ast.Attribute) and operand.attr == "kind" and "robot" in ast.unparse(operand.value):
                lines.append(node.lineno)
    return lines


def test_only_the_robot_registry_compares_robot_kind():
    """A robot kind is one object of ``ident_hw.config.robots``: nothing else branches on its name."""
    found = {name: _robot_kind_compares(path) for name, path in MODULES.items() if name != "ident_hw.config.robots"}
    assert {name: lines for name, lines in found.items() if lines} == {}


def test_the_check_finds_a_robot_kind_comparison(tmp_path):
    source = tmp_path / "branching.py"
    source.write_text("def f(config):\n    if config.robot.kind == 'delta':\n        return 1\n"
                      "    return self.robot.kind in ('3prrr',)\n")
    assert _robot_kind_compares(source) == [2, 4]


def test_the_model_and_the_drivers_name_joint_kinds_alike():
    """The layers keep the model's and the drivers' joint kinds apart (neither may import the
    other); the config compares an axis' kind with its joint's, so the two pairs must agree."""
    from drivers import units
    from ident_hw.model import interface
    assert (units.REVOLUTE, units.PRISMATIC) == (interface.REVOLUTE, interface.PRISMATIC)
