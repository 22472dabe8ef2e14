"""Sphinx configuration of the API reference: autodoc of the ``ident_hw``, ``drivers`` and ``trajectories``
packages, Google-style docstrings read by napoleon.

Built by the README's test command and by ``.ci/run``, warnings as errors::

    python -m sphinx -W --keep-going -E -j auto -q -b html docs docs/_build/html

The markdown pages beside this file are read on their own (``docs/README.md``); the build reads only the
reStructuredText pages (``index.rst``, ``api/*.rst``). Importing the modules opens no bus and starts nothing.
"""

import importlib
import sys
from pathlib import Path

from sphinx.util import logging

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # the packages of this checkout, whichever one is installed

PACKAGES = ("ident_hw", "drivers", "trajectories")

project = "ident_hw"
author = "ident_hw contributors"
copyright = "ident_hw contributors"

# (sphinx.ext.viewcode would add the highlighted sources, but it more than doubled the build's time)
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon"]

root_doc = "index"
source_suffix = {".rst": "restructuredtext"}
exclude_patterns = ["_build", "**/__pycache__"]

# a package's ``__all__`` names what it re-exports; each object is documented once, in the module that
# defines it (documenting the re-exports too would give every cross-reference to them two targets)
autodoc_default_options = {"members": True, "show-inheritance": True, "ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"

napoleon_google_docstring = True
napoleon_numpy_docstring = False

# every cross-reference resolves (nitpicky), but to the libraries' own objects: their inventories
# (intersphinx) would be downloaded at each build, so the names of NumPy, SciPy, the standard
# library, python-can, canopen, PyYAML and pinocchio stay text; so do the type-variable and generic
# fragments autodoc makes of annotations (``tuple[float, ...]`` read as a class name)
nitpicky = True
_LIBRARIES = (r"numpy|np|scipy|pathlib|Path|os|collections|typing|enum|contextlib|logging|gc|dataclasses|"
              r"abc|can|canopen|yaml|jinja2|matplotlib|pinocchio")
nitpick_ignore_regex = [
    (r"py:.*", rf"({_LIBRARIES})(\..*)?"),
    (r"py:.*", r"(tuple|dict|list|set|frozenset|type|Literal|Mapping|Sequence|Callable)\[.*"),
    (r"py:class", r"ident_hw\.storage\.T"),
]

html_theme = "alabaster"
html_title = "ident_hw API reference"
html_static_path: list[str] = []


def public_modules() -> set[str]:
    """Every public module of the three packages, found from the files (no import)."""
    names = set()
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            parts = path.relative_to(ROOT).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            if any(part.startswith("_") for part in parts):
                continue
            names.add(".".join(parts))
    return names


def check_every_module_documented(app, env) -> None:
    """A warning (an error under ``-W``) for each public module no page of ``api/`` documents."""
    documented = set(env.get_domain("py").data["modules"])
    for name in sorted(public_modules() - documented):
        logging.getLogger(__name__).warning("module %s is in no page of the API reference (docs/api/)", name)


# napoleon reads the first line of an attribute's, a constant's or a property's docstring as ``type: text``
# (Google style's inline attribute type); the project's are prose ("The SYNC producer of the runs: ..."), and
# their types come from the annotations. Those docstrings are kept as written (napoleon parses no section in
# them anyway).
_ATTRIBUTE_LIKE = ("attribute", "data", "property")
_attribute_docstrings: dict[str, list[str]] = {}


def keep_attribute_docstring(app, what, name, obj, options, lines) -> None:
    """Before napoleon: the lines of an attribute-like docstring as written."""
    if what in _ATTRIBUTE_LIKE:
        _attribute_docstrings[name] = list(lines)


def restore_attribute_docstring(app, what, name, obj, options, lines) -> None:
    """After napoleon: those lines back."""
    if what in _ATTRIBUTE_LIKE and name in _attribute_docstrings:
        lines[:] = _attribute_docstrings.pop(name)


def _documented_name(dotted: str) -> str | None:
    """Where the object ``dotted`` names is defined (``ident_hw.model.ThreePRRR`` →
    ``ident_hw.model.robot.ThreePRRR``); None outside the packages. Imports as autodoc does (in a parallel
    build, the process that resolves references is not the one that read the module)."""
    parts = dotted.split(".")
    if parts[0] not in PACKAGES:
        return None
    for i in range(len(parts), 0, -1):
        try:
            module = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        break
    else:
        return None
    obj, name = module, module.__name__
    for part in parts[i:]:
        try:
            obj = getattr(obj, part)
        except AttributeError:
            return None
        if isinstance(obj, type(sys)):
            name = obj.__name__
        elif isinstance(getattr(obj, "__module__", None), str) and isinstance(getattr(obj, "__qualname__", None), str):
            name = f"{obj.__module__}.{obj.__qualname__}"
        else:
            name = f"{name}.{part}"
    return name if name.split(".")[0] in PACKAGES else None


def resolve_imported_name(app, env, node, contnode):
    """A cross-reference to a name a module imports or re-exports (``ident_hw.model.ThreePRRR``,
    :class:`Plant` in :mod:`drivers.sim.rig`), resolved to the object's entry where it is defined."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"]
    candidates = [target]
    if node.get("py:module"):
        candidates.insert(0, f"{node['py:module']}.{target}")
        if node.get("py:class"):
            candidates.insert(0, f"{node['py:module']}.{node['py:class']}.{target}")
    domain = env.get_domain("py")
    for dotted in candidates:
        name = _documented_name(dotted)
        if name is not None and name != dotted:
            resolved = domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"], name, node, contnode)
            if resolved is not None:
                return resolved
    return None


def setup(app):
    app.connect("env-updated", check_every_module_documented)
    app.connect("autodoc-process-docstring", keep_attribute_docstring, priority=400)
    app.connect("autodoc-process-docstring", restore_attribute_docstring, priority=600)
    app.connect("missing-reference", resolve_imported_name)
