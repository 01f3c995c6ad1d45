# SPDX-License-Identifier: Apache-2.0
"""docs/architecture.md against the code: the module count, the import circles and levels, the
layer table (which modules each row holds, what they import from h4pin, what they never import,
that no module imports one of a higher layer), the validation routes the package never imports,
and the size limits it states. Both sides are read at test time (the source with ``ast``, nothing
imported), so a module added on any branch fails here until the page says where it lives."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "h4pin"
DOC = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")


def _name(path: Path) -> str:
    """The module's dotted name: ``h4pin.a.b`` (a package is its ``__init__``)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


FILES = {_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}
TREES = {m: ast.parse(p.read_text(encoding="utf-8")) for m, p in FILES.items()}


def _imports(module: str) -> set[str]:
    """The h4pin modules ``module`` imports anywhere (inside functions and under TYPE_CHECKING
    too): ``from a import b`` names the module a.b when it is one, else a."""
    package = module if FILES[module].name == "__init__.py" else module.rpartition(".")[0]
    out = set()
    for node in ast.walk(TREES[module]):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(up + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in FILES else base for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in FILES:
                t = t.rpartition(".")[0]
            if t and t != module:
                out.add(t)
    return out


GRAPH = {m: _imports(m) for m in FILES}


def _is_face(module: str) -> bool:
    """An ``__init__`` under 40 lines that only hands names on (imports, docstring, ``__all__``)."""
    path, tree = FILES[module], TREES[module]
    if path.name != "__init__.py" or len(path.read_text(encoding="utf-8").splitlines()) >= 40:
        return False
    return all(isinstance(n, (ast.Import, ast.ImportFrom, ast.Expr))
               or (isinstance(n, ast.Assign) and all(getattr(t, "id", "") == "__all__" for t in n.targets))
               for n in tree.body)


FACES = {m for m in FILES if _is_face(m)}


def _circles() -> list[set[str]]:
    """The import circles: strongly connected groups of more than one module (faces left out)."""
    graph = {m: {d for d in GRAPH[m] if d not in FACES} for m in FILES}

    def reach(start: str) -> set[str]:
        seen, todo = set(), [start]
        while todo:
            for d in graph[todo.pop()] - seen:
                seen.add(d)
                todo.append(d)
        return seen

    closure = {m: reach(m) for m in graph}
    groups = {frozenset({m} | {d for d in closure[m] if m in closure[d]}) for m in graph}
    return [set(g) for g in groups if len(g) > 1]


def _levels() -> dict[str, int]:
    """Each module's level: one above the highest it imports (1 for none; faces not counted)."""
    level: dict[str, int] = {}

    def of(m: str) -> int:
        if m not in level:
            level[m] = 1 + max((of(d) for d in GRAPH[m] if d not in FACES), default=0)
        return level[m]

    for m in FILES:
        of(m)
    return level


def _number(pattern: str) -> str:
    found = re.search(pattern, DOC)
    assert found, f"docs/architecture.md no longer states {pattern!r}"
    return found.group(1)


def _covered(module: str, names: set[str]) -> bool:
    """``module`` is one of ``names`` or inside one of them (a package covers its modules)."""
    return any(module == n or module.startswith(n + ".") for n in names)


def _table() -> list[dict]:
    """The rows of the "Layers" table: layer number, name, modules, imports, never-imports."""
    section = DOC.split("\n## Layers\n", 1)[1].split("\n## ", 1)[0]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not re.match(r"^(\d+ |face\b)", cells[0]):
            continue
        layer, modules, package = cells[0], set(), None
        for token in re.findall(r"`([^`]+)`", cells[1]):
            if token.endswith("/"):
                package = "h4pin." + token[:-1].replace("/", ".")
            elif token.endswith(".py"):
                modules.add("h4pin" if token == "__init__.py" else "h4pin." + token[:-3])
            else:
                modules.add(package if token == "__init__" else f"{package or 'h4pin'}.{token}")
        allowed, _, never = cells[3].partition("never")
        rows.append({"layer": -1 if layer.startswith("face") else int(layer.split()[0]), "name": layer,
                     "modules": modules,
                     "imports": {"h4pin." + t for t in re.findall(r"`([^`]+)`", allowed)},
                     "never": {"h4pin." + t for t in re.findall(r"`([^`]+)`", never)}})
    return rows


TABLE = _table()


def test_the_counts_are_those_of_the_code():
    """"N modules", "no import circle" and "L levels" as the source has them now."""
    assert int(_number(r"\*\*(\d+) modules\*\*")) == len(FILES)
    assert _number(r"\*\*(no import circle)\*\*") and _circles() == []
    assert int(_number(r"\*\*(\d+) levels\*\*")) == max(_levels().values())


def test_every_module_sits_in_one_row_of_the_layer_table():
    assert len(TABLE) >= 10
    listed = [m for row in TABLE for m in row["modules"]]
    assert sorted(listed) == sorted(set(listed)), "a module is in two rows"
    assert set(listed) == set(FILES), (f"in the code, not the table: {sorted(set(FILES) - set(listed))}; "
                                       f"in the table, not the code: {sorted(set(listed) - set(FILES))}")


@pytest.mark.parametrize("row", TABLE, ids=[r["name"] for r in TABLE])
def test_a_rows_imports_are_what_the_table_says(row):
    """What the row's modules import from the rest of h4pin is exactly its "Imports" cell (a
    package name covers its modules, and each name given is imported), nothing after "never" is
    imported, and nothing is imported from a row of a higher layer."""
    used = {d for m in row["modules"] for d in GRAPH[m]} - row["modules"]
    assert {d for d in used if not _covered(d, row["imports"])} == set(), "imported, not in the table"
    assert {n for n in row["imports"] if not any(_covered(d, {n}) for d in used)} == set(), "in the table, not imported"
    assert {d for d in used if _covered(d, row["never"])} == set(), "imported, though the table says never"
    layer = {m: r["layer"] for r in TABLE for m in r["modules"]}
    if row["layer"] >= 0:  # the face hands on names from every layer
        assert {d for d in used if layer[d] > row["layer"]} == set(), "imports from a higher layer"


def test_the_validation_routes_are_imported_by_no_module_of_the_package():
    """The data-flow sketch: checks.* are "imported by tests, never by the package"."""
    assert "imported by tests, never by the package" in DOC
    importers = {m for m, deps in GRAPH.items()
                 if not _covered(m, {"h4pin.checks"}) and any(_covered(d, {"h4pin.checks"}) for d in deps)}
    assert importers == set()


def test_no_class_and_no_function_is_longer_than_the_page_says():
    classes = int(_number(r"no class over (\d+)\s+lines"))
    functions = int(_number(r"no function over (\d+)\s+lines"))
    for module, tree in TREES.items():
        for node in ast.walk(tree):
            size = getattr(node, "end_lineno", 0) - getattr(node, "lineno", 0) + 1
            if isinstance(node, ast.ClassDef):
                assert size <= classes, f"{module}.{node.name}: {size} lines"
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                assert size <= functions, f"{module}:{node.name}: {size} lines"


#: The H4's own modules: what the generic engine (h4pin.mechanism) must not reach.
H4_SIDE = {"h4pin.description", "h4pin.descriptions", "h4pin.kinematics", "h4pin.robot", "h4pin.stiffness",
           "h4pin.elastic", "h4pin.checks", "h4pin.studies", "h4pin.io", "h4pin.vibration", "h4pin.plots",
           "h4pin.cli", "h4pin.warmup"}


def test_the_generic_engine_reaches_nothing_of_the_h4():
    """The import closure of every module of h4pin.mechanism (what it imports, what those import,
    and so on; inside functions too) holds no module of the H4, nor the package's face, which
    imports the H4: the engine is the bottom floor, the H4 its client."""
    for module in (m for m in FILES if _covered(m, {"h4pin.mechanism"})):
        seen, todo = set(), [module]
        while todo:
            for d in GRAPH[todo.pop()] - seen:
                seen.add(d)
                todo.append(d)
        reached = sorted(d for d in seen if _covered(d, H4_SIDE) or d == "h4pin")
        assert reached == [], f"{module} reaches {reached}"
    assert "floor 1   mechanism/" in DOC  # the page draws it under the H4's floors


def test_the_files_ci_reads_exist():
    """Every file of this repository .ci/run names (the tests it runs, the modules it reads a
    version bound from) exists, and each bound it reads with sed is found: a move that forgets CI
    fails here, not on the fresh machine."""
    text = (ROOT / ".ci" / "run").read_text()
    paths = set(re.findall(r"\b((?:h4pin|tests|scripts|docs)/[\w/.-]+\.(?:py|toml|md))\b", text))
    assert paths, "no path found in .ci/run"
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert not missing, missing
    for pattern, path in re.findall(r"sed -n '(s/[^']+)' (\S+)\)", text):
        regex = pattern.split("/")[1].replace(r"\(", "(").replace(r"\)", ")")
        found = re.search(regex, (ROOT / path).read_text(), re.MULTILINE)
        assert found, (pattern, path)
