"""The project's import layers (developers' brief), checked on the source with ``ast``.

* ``ident_hw.model`` is pure math: it imports nothing else of the project; ``ident_hw.storage``
  (records to JSON) and ``ident_hw.progress`` neither.
* ``trajectories`` and the simulated rig (``drivers.sim``) may import the model, nothing above it.
* the drive driver (``drivers`` outside ``drivers.sim``) never imports ``ident_hw`` nor the rig.
* only the experiment runner (``ident_hw.experiment``) and the CLI wire drivers and trajectories
  together; the config maps YAML to the drivers' settings, and imports nothing of ``trajectories``.
* the results (``ident_hw.records``, ``ident_hw.results``) and their report (``ident_hw.report``)
  know nothing of the config, the runner, the drivers or the trajectories: a results folder is
  read and rendered on its own; the results import nothing of the report.
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


def test_storage_and_progress_import_nothing_of_the_project():
    for module in ("ident_hw.storage", "ident_hw.progress"):
        assert offenders(module, PACKAGES) == [], module


def test_config_imports_no_trajectories_runner_results_or_report():
    assert offenders("ident_hw.config", ("trajectories", "ident_hw.experiment", "ident_hw.results",
                                         "ident_hw.records", "ident_hw.report")) == []


def test_results_and_report_know_nothing_of_config_runner_drivers_or_trajectories():
    """The report is the bottom of the upper half: it renders a results folder from its files alone."""
    forbidden = ("ident_hw.config", "ident_hw.experiment", "drivers", "trajectories", "ident_hw.cli")
    for layer in ("ident_hw.records", "ident_hw.results", "ident_hw.report"):
        assert offenders(layer, forbidden) == [], layer
    assert offenders("ident_hw.results", ("ident_hw.report",)) == []
    assert offenders("ident_hw.records", ("ident_hw.results", "ident_hw.report")) == []


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
    # ident_hw.config maps YAML to the drivers' own settings classes: allowed (the trajectories: not)
    assert [(m, i) for m, i in bad if not (within(m, "ident_hw.config") and within(i, "drivers"))] == []


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


# ----------------------------------------------------------------------------- the runner's inputs
#: the functions of ident_hw.experiment that take the whole Config: the commands' entry points
#: (what ident_hw.cli calls), and the edge that makes the config into the typed inputs every other
#: function takes parts of (an identification plan, a campaign's plan, its streaming, its drives)
CONFIG_ENTRY_POINTS = {
    "plan.plan", "plan.check_campaign", "runner.run_campaign", "runner.identify_recordings", "offline.identify",
    "recordings.gather_recordings", "recordings.RecordingChecks.of",
    "external.read_external", "folders.new_results_folder", "session.open_session", "session.simulated_rig",
    "session.HostSettings.for_command", "inspection.compare", "campaign_estimator.CampaignEstimator.__init__",
    "inputs.identification_plan", "plan.PlanInputs.of", "runner.CampaignInputs.of", "session.DriveSettings.of",
    "excitation.optimised_sines",
}


def _functions(tree: ast.AST, prefix: str = ""):
    """(qualified name, node) of every function of a module, methods as ``Class.method``."""
    for node in getattr(tree, "body", []):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield f"{prefix}{node.name}", node
        elif isinstance(node, ast.ClassDef):
            yield from _functions(node, f"{prefix}{node.name}.")


def test_only_the_runner_s_entry_points_take_the_whole_config():
    """The config travels no further than the edge: every other function of the runner takes the
    parts it uses (issue 49)."""
    found = set()
    for path in sorted((ROOT / "ident_hw" / "experiment").glob("*.py")):
        for name, node in _functions(ast.parse(path.read_text())):
            args = node.args.posonlyargs + node.args.args + node.args.kwonlyargs
            if any(a.annotation is not None and ast.unparse(a.annotation).split("|")[0].strip() == "Config"
                   for a in args):
                found.add(f"{path.stem}.{name}")
    assert found == CONFIG_ENTRY_POINTS


#: public functions whose annotations hold a dict of text keys by what they are: a dataclass
#: field's metadata (dataclasses' own API), a dataclass's field values by name (its keyword
#: arguments: the config loader's ``given``), a JSON document (a file's, a record's older one)
JSON_DOCUMENTS = {"ident_hw.config.schema.spec", "ident_hw.config.schema.build", "ident_hw.storage.stored",
                  "ident_hw.storage.file_document",
                  "ident_hw.records.RecordingCoverage.upgrade_json", "ident_hw.records.TrajectoryVerdict.upgrade_json",
                  "ident_hw.records.Verdict.upgrade_json", "ident_hw.results.folder.ResultsFile.upgrade_json",
                  # the drivers' and trajectories' stored forms: a PDO layout stored with a recording and
                  # beside its raw log, a recorded axis in a recording's metadata, an excitation's file
                  "drivers.acquisition.layout_record", "drivers.recording_metadata.RecordedAxis.to_json",
                  "drivers.recording_metadata.RecordedAxis.from_json", "trajectories.fourier.FourierExcitation.to_dict",
                  "trajectories.joint_space.OptimisedFor.from_json",
                  # a bus section of YAML as written (its unknown keys go on to python-can as options)
                  "drivers.bus.BusConfig.from_mapping"}

def _bare_record(annotation: ast.expr) -> bool:
    """A tuple of more than two items, or a dict with text keys of anything (a record in disguise)."""
    for sub in ast.walk(annotation):
        if isinstance(sub, ast.Subscript) and ast.unparse(sub.value) in ("tuple", "Tuple"):
            items = sub.slice.elts if isinstance(sub.slice, ast.Tuple) else [sub.slice]
            if len(items) > 2 and not any(isinstance(i, ast.Constant) and i.value is Ellipsis for i in items):
                return True
    text = ast.unparse(annotation).replace(" ", "")
    return text in ("dict", "Dict", "Mapping") or any(text.startswith(f"{d}[str,Any]") or text.startswith(f"{d}[str,object]")
                                                     for d in ("dict", "Mapping", "Dict"))


def _returns_a_bare_tuple(function: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """``return a, b, c`` (a tuple display of more than two items) in ``function``'s own body (not
    in a function nested in it): what an unannotated function returns that the annotations miss."""
    stack = list(function.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        if isinstance(node, ast.Return) and isinstance(node.value, ast.Tuple) and len(node.value.elts) > 2:
            return True
        stack.extend(ast.iter_child_nodes(node))
    return False


def _bare_records(path: Path) -> list[str]:
    """Public functions of ``path`` (qualified names) that take or return a bare record: a tuple
    of more than two items or a dict of text keys in an annotation, or, without a return
    annotation, a ``return`` of a tuple of more than two items (an annotated return is what mypy
    holds the function to: ``tuple[PhysicalBody, ...]`` is no record in disguise); a module's
    own helpers (``_name``) are skipped."""
    found = []
    for qualified, node in _functions(ast.parse(path.read_text())):
        if any(part.startswith("_") and part != "__init__" for part in qualified.split(".")):
            continue
        annotations = [node.returns] + [a.annotation for a in node.args.args + node.args.kwonlyargs]
        if (any(a is not None and _bare_record(a) for a in annotations)
                or (node.returns is None and _returns_a_bare_tuple(node))):
            found.append(qualified)
    return found


def test_no_tuple_of_more_than_two_items_nor_dict_record_crosses_a_module_boundary():
    """What a public function of ident_hw, drivers or trajectories takes or returns is a record,
    not a bare tuple of three or more items or a dict of text keys (issue 49); a module's own
    helpers (``_name``) may."""
    found = {f"{name}.{qualified}" for name, path in MODULES.items() for qualified in _bare_records(path)}
    assert sorted(found - JSON_DOCUMENTS) == []


def test_the_check_finds_bare_records(tmp_path):
    """The check sees a triple in an annotation, in a callable's, and in an unannotated return;
    not a pair, a variable-length tuple (nor the display an annotated one returns), a nested
    helper's return, nor a private function."""
    source = tmp_path / "shapes.py"
    source.write_text("def annotated(x) -> tuple[int, int, int]:\n    return x\n"
                      "def takes(f: Callable[[int], tuple[int, int, int]]):\n    return f\n"
                      "def bare(x):\n    if x:\n        return x, x, x\n    return None\n"
                      "def documents() -> dict:\n    return {}\n"
                      "class C:\n    def method(self):\n        return 1, 2, 3\n"
                      "def pair(x) -> tuple[int, int]:\n    return x, x\n"
                      "def any_length(x) -> tuple[int, ...]:\n    return x\n"
                      "def nested(x):\n    def inner():\n        return x, x, x\n    return inner\n"
                      "def bodies() -> tuple[int, ...]:\n    return 1, 2, 3\n"
                      "def _private(x):\n    return x, x, x\n")
    assert _bare_records(source) == ["annotated", "takes", "bare", "documents", "C.method"]
