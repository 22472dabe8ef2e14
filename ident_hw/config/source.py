"""Reading config files into one composed YAML node tree, resolving ``extends:``.

A file may start with ``extends: base.yaml`` (or a list of files; paths relative to the file
that names them). The bases are merged in order, then the file itself on top: mappings merge
key by key (recursively), anything else (numbers, lists) is replaced. Every node keeps the mark
of the file and line it came from, so errors point at the right file.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from .schema import ConfigError, error_at, mapping_items

EXTENDS = "extends"
_TAG_MERGE = "tag:yaml.org,2002:merge"


def compose_file(path: str | Path, _chain: tuple[Path, ...] = ()) -> yaml.MappingNode:
    """Compose ``path`` and everything it extends into one mapping node."""
    path = Path(path)
    try:
        with open(path, encoding="utf-8") as stream:
            node = yaml.compose(stream, Loader=yaml.SafeLoader)
    except FileNotFoundError:
        raise ConfigError("file not found", file=str(path)) from None
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror}", file=str(path)) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a text file (byte 0x{exc.object[exc.start]:02X} at offset {exc.start} is not "
                          "UTF-8): a config is a YAML text file", file=str(path)) from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark else None
        raise ConfigError(f"not valid YAML: {exc.problem or exc.context}", file=str(path), line=line) from None
    except yaml.YAMLError as exc:   # the reader's errors: NUL and other control characters
        line = _line_of(path, getattr(exc, "position", None))
        why = f"character 0x{exc.character:02X} is not allowed in YAML" if isinstance(
            getattr(exc, "character", None), int) else str(exc).splitlines()[0]
        raise ConfigError(f"not valid YAML: {why}", file=str(path), line=line) from None
    if node is None:
        raise ConfigError("the file is empty", file=str(path))
    _flatten_merge_keys(node, set())
    items = mapping_items(node, "")
    if EXTENDS not in items:
        return node
    key_node, value_node = items[EXTENDS]
    if isinstance(value_node, yaml.ScalarNode) and value_node.tag == "tag:yaml.org,2002:str":
        bases = [value_node]
    elif isinstance(value_node, yaml.SequenceNode) and all(
            isinstance(n, yaml.ScalarNode) and n.tag == "tag:yaml.org,2002:str" for n in value_node.value):
        bases = value_node.value
    else:
        raise error_at(value_node, EXTENDS, "expected a file name or a list of file names")
    resolved = path.resolve()
    merged: yaml.MappingNode | None = None
    for base_node in bases:
        base_path = (path.parent / base_node.value)
        if base_path.resolve() in (*_chain, resolved):
            raise error_at(base_node, EXTENDS, f"{base_node.value!r} extends itself (cycle)")
        if not base_path.is_file():
            raise error_at(base_node, EXTENDS, f"base file {base_node.value!r} not found "
                                               f"(looked for {base_path})")
        base = compose_file(base_path, (*_chain, resolved))
        merged = base if merged is None else merge(merged, base)
    own = yaml.MappingNode(node.tag, [(k, v) for k, v in node.value if k.value != EXTENDS],
                           node.start_mark, node.end_mark)
    return merge(merged, own)


def _line_of(path: Path, position: int | None) -> int | None:
    """1-based line of character ``position`` of a text file (None when unknown)."""
    if position is None:
        return None
    try:
        return path.read_text(encoding="utf-8")[:position].count("\n") + 1
    except (OSError, UnicodeDecodeError):
        return None


def _flatten_merge_keys(node: yaml.Node, done: set[int]) -> None:
    """Resolve YAML merge keys (``<<: *anchor``) in place: the mapping's own keys win."""
    if id(node) in done:
        return
    done.add(id(node))
    if isinstance(node, yaml.SequenceNode):
        for child in node.value:
            _flatten_merge_keys(child, done)
    if not isinstance(node, yaml.MappingNode):
        return
    own, inherited = [], []
    for key_node, value_node in node.value:
        if key_node.tag != _TAG_MERGE:
            own.append((key_node, value_node))
            _flatten_merge_keys(value_node, done)
            continue
        sources = value_node.value if isinstance(value_node, yaml.SequenceNode) else [value_node]
        for source in sources:
            if not isinstance(source, yaml.MappingNode):
                raise error_at(source, "<<", "a merge key needs a mapping (or a list of mappings)")
            _flatten_merge_keys(source, done)
            inherited.extend(source.value)
    names = {k.value for k, _ in own}
    for key_node, value_node in inherited:
        if key_node.value not in names:
            names.add(key_node.value)
            own.insert(0, (key_node, value_node))
    node.value = own


def merge(base: yaml.Node, override: yaml.Node) -> yaml.Node:
    """Deep-merge two composed nodes: mappings key by key, everything else replaced."""
    if not (isinstance(base, yaml.MappingNode) and isinstance(override, yaml.MappingNode)):
        return override
    out = list(base.value)
    index = {k.value: i for i, (k, _) in enumerate(out)}
    for key_node, value_node in override.value:
        i = index.get(key_node.value)
        if i is None:
            index[key_node.value] = len(out)
            out.append((key_node, value_node))
        else:
            out[i] = (key_node, merge(out[i][1], value_node))
    return yaml.MappingNode(override.tag, out, override.start_mark, override.end_mark)
